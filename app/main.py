"""The FastAPI application: ``create_app(settings)`` (the lifespan owns the engine) and ``run_server``."""

from __future__ import annotations

import logging
import socket
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse
from fastapi.routing import APIRoute
from fastapi.staticfiles import StaticFiles
from starlette.requests import Request
from starlette.responses import Response

from app import errors
from app.auth import Role, lookup
from app.guard import RequestGuard
from app.metrics import MetricsMiddleware
from app.routes import ALL_ROUTERS, ops
from app.service import Service
from app.settings import Settings, load_settings
from app.view_proxy import VIEW_PATH
from tracker.errors import ConfigError
from tracker.plant.effects import load_effect_modules
from tracker.resources import project_dir

STATIC_DIR = project_dir("static")
API_PREFIX = "/api/v1"

DESCRIPTION = """
REST and WebSocket API of the 3DAT console: a pan/tilt camera steered toward whoever talks.

Send your API key in the `X-API-Key` header. Roles: **viewer** (read) < **operator** (tracking,
pointing, presets) < **engineer** (gains, workbench, jobs, practice rig) < **admin** (keys).
Angles are degrees. Errors are JSON `{"detail": str, "error": kind, ...}`: 401/403 auth, 404
unknown axis or resource, 409 manual control held by someone else, 422 out of range (the body
names the limit), unsafe gains (with the margins) or an invalid body (`errors` lists the first
problems), 400 malformed data (the body names the line and column), 413 body, upload or
measurement over its cap (the body names the setting), 429 too many bad keys from one address or
too much heavy work at once (with `Retry-After`), 503 driver fault. Changes are written to an audit
log (`GET /audit`, admins). Outside this API: `GET /metrics` (Prometheus) and `GET /health`.
"""


def create_app(settings: Settings | None = None, banner_port: int | None = None) -> FastAPI:
    """The console application for ``settings`` (defaults: simulated room and rig, ./data).

    With ``banner_port`` (the port the server bound) the start banner is printed once started.
    """
    settings = settings or load_settings()
    load_effect_modules(settings.effects, "effects setting")

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        svc = Service(settings)
        app.state.svc = svc
        app.state.db = svc.db
        await svc.start()
        if banner_port is not None:
            print("\n".join(banner_lines(settings, svc, banner_port)), flush=True)
        try:
            yield
        finally:
            await svc.stop()

    app = FastAPI(
        title="3DAT console",
        version="1.0",
        description=DESCRIPTION,
        lifespan=lifespan,
        docs_url=None,  # served below with local assets
        redoc_url=None,
        openapi_url=f"{API_PREFIX}/openapi.json",
    )
    errors.install(app)
    for router in ALL_ROUTERS:
        app.include_router(router, prefix=API_PREFIX)
    api_routes = [r for router in ALL_ROUTERS for r in router.routes if isinstance(r, APIRoute)]
    # Inside security_headers below (the last added is outermost).
    app.add_middleware(RequestGuard, prefix=API_PREFIX, routes=api_routes)

    @app.middleware("http")
    async def security_headers(request: Request, call_next: object) -> Response:
        response: Response = await call_next(request)  # type: ignore[operator]
        response.headers.setdefault("X-Content-Type-Options", "nosniff")
        response.headers.setdefault("Referrer-Policy", "no-referrer")
        if request.url.path.startswith("/api/"):
            response.headers.setdefault("Cache-Control", "no-store")
        return response

    app.add_middleware(MetricsMiddleware)  # outermost: times everything, refusals included
    app.include_router(ops.router)  # /metrics and /health, outside the API's prefix

    @app.get("/", include_in_schema=False)
    async def index() -> FileResponse:
        return FileResponse(STATIC_DIR / "index.html")

    @app.get("/api/docs", include_in_schema=False)
    async def api_docs() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=f"{API_PREFIX}/openapi.json",
            title="3DAT console API",
            swagger_js_url="/static/vendor/swagger-ui-bundle.js",
            swagger_css_url="/static/vendor/swagger-ui.css",
            swagger_favicon_url="data:,",
        )

    @app.get("/docs", include_in_schema=False)
    async def docs_redirect() -> RedirectResponse:
        return RedirectResponse("/api/docs")

    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    return app


def banner_lines(settings: Settings, svc: Service, port: int) -> list[str]:
    """What the start banner says: the console's address on the port bound, where the first
    admin key is (only while that key still works), the 3D view through the console and viser's
    own (loopback) port as bound."""
    shown_host = "127.0.0.1" if settings.host in {"0.0.0.0", "::"} else settings.host
    lines = [f"3DAT console: http://{shown_host}:{port}/  (API docs: /api/docs)"]
    if first_admin_key_valid(svc, settings.admin_key_path):
        where = settings.admin_key_path.resolve()
        lines.append(f"3DAT console: sign in with an API key; the first admin key is in {where}")
    else:
        lines.append("3DAT console: sign in with an API key (an admin creates keys on the Keys page)")
    if svc.viewer is not None:
        lines.append(
            f"3DAT console: 3D view on http://{shown_host}:{port}{VIEW_PATH}/ (through the console, its keys)"
        )
        lines.append(
            f"3DAT console: viser itself listens on http://{svc.viewer.host}:{svc.viewer.port}/ "
            "(no authentication: keep it on loopback)"
        )
    elif settings.viewer_enabled:
        lines.append("3DAT console: the 3D view did not start (see the log)")
    return lines


def first_admin_key_valid(svc: Service, key_path: Path) -> bool:
    """True when ``key_path`` holds an admin key that is neither unknown nor revoked."""
    try:
        key = key_path.read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        return False
    who = lookup(svc.db, key)
    return who is not None and who.role == Role.admin


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host``:``port`` (0 picks a free port); ConfigError when taken."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise ConfigError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.listen(2048)  # connections queue from now on, so the banner's address answers at once
    sock.set_inheritable(True)
    return sock


def run_server(
    host: str | None = None, port: int | None = None, config: str | None = None, rig_config: str | None = None
) -> None:
    """Start the console with uvicorn (``tracker serve``); blocks until interrupted.

    Command-line values (``host``, ``port``, ``rig_config``) beat the environment and the file.
    The socket is bound first, so the banner prints the port actually bound (``port = 0`` too).
    """
    import uvicorn

    settings = load_settings(config, host=host, port=port, rig_config=rig_config)
    from app.rig import check_settings

    check_settings(settings)
    logging.basicConfig(
        level=settings.log_level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    sock = bind(settings.host, settings.port)
    bound_port = int(sock.getsockname()[1])
    app = create_app(settings, banner_port=bound_port)
    server_config = uvicorn.Config(
        app,
        host=settings.host,
        port=bound_port,
        log_level=settings.log_level,
        ws_ping_interval=20.0,
        ws_max_size=settings.max_body_bytes,  # a WebSocket message is capped like a body
    )
    uvicorn.Server(server_config).run(sockets=[sock])
