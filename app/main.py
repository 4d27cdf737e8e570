"""The FastAPI application: ``create_app(settings)`` (the lifespan owns the engine) and ``run_server``."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles
from starlette.requests import Request
from starlette.responses import Response

from app import errors
from app.routes import ALL_ROUTERS
from app.service import Service
from app.settings import Settings, load_settings

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"
API_PREFIX = "/api/v1"

DESCRIPTION = """
REST and WebSocket API of the 3DAT console: a pan/tilt camera steered toward whoever talks.

Send your API key in the `X-API-Key` header. Roles: **viewer** (read) < **operator** (tracking,
pointing, presets) < **engineer** (gains, workbench, jobs, practice rig) < **admin** (keys).
Angles are degrees. Errors: 401/403 auth, 404 unknown axis or resource, 409 manual control held by
someone else, 422 out of range (the body names the limit) or unsafe gains (with the margins),
400 malformed data (the body names the line and column), 503 driver fault.
"""


def create_app(settings: Settings | None = None) -> FastAPI:
    """The console application for ``settings`` (defaults: simulated room and rig, ./data)."""
    settings = settings or load_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        svc = Service(settings)
        app.state.svc = svc
        app.state.db = svc.db
        await svc.start()
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

    @app.middleware("http")
    async def security_headers(request: Request, call_next: object) -> Response:
        response: Response = await call_next(request)  # type: ignore[operator]
        response.headers.setdefault("X-Content-Type-Options", "nosniff")
        response.headers.setdefault("Referrer-Policy", "no-referrer")
        if request.url.path.startswith("/api/"):
            response.headers.setdefault("Cache-Control", "no-store")
        return response

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


def run_server(
    host: str | None = None, port: int | None = None, config: str | None = None, rig_config: str | None = None
) -> None:
    """Start the console with uvicorn (``tracker serve``); blocks until interrupted.

    Command-line values (``host``, ``port``, ``rig_config``) beat the environment and the file.
    """
    import uvicorn

    settings = load_settings(config, host=host, port=port, rig_config=rig_config)
    from app.rig import check_settings

    check_settings(settings)
    logging.basicConfig(
        level=settings.log_level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    shown_host = "127.0.0.1" if settings.host in {"0.0.0.0", "::"} else settings.host
    print(f"3DAT console: http://{shown_host}:{settings.port}/  (API docs: /api/docs)", flush=True)
    if settings.admin_key_path.exists():
        print(
            "3DAT console: sign in with an API key; the first admin key is in "
            f"{settings.admin_key_path.resolve()}",
            flush=True,
        )
    if settings.viewer_enabled:
        print(
            f"3DAT console: 3D view on http://{settings.viewer_host}:{settings.viewer_port}/ "
            "(loopback only by "
            "default; it has no authentication)",
            flush=True,
        )
    uvicorn.run(
        create_app(settings),
        host=settings.host,
        port=settings.port,
        log_level=settings.log_level,
        ws_ping_interval=20.0,
    )
