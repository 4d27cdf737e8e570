"""The request guard (ASGI middleware): key, back-off and body size are checked before the body is read.

FastAPI reads and parses a request's body before it runs the route's dependencies, so a route's
own key check comes after a 200 MB upload has been read. The guard finds the route a request
will reach, and for routes that need a role (``auth.RequireRole`` among their dependencies) it
answers 401/403 at once, or 429 with Retry-After while the client address is blocked for bad
keys (app/backoff.py). Then it enforces the body limit: ``max_upload_bytes`` for routes that
take a file upload, ``max_body_bytes`` for the rest; a Content-Length over the limit is refused
before anything is read, and a body that streams past it is cut off with 413. A request that
no route takes is left to the router, which answers 404 (or 405) without reading the body: an
upload to a wrong path is told the path is wrong, not that it is too large. Every refusal is
the JSON error of app/errors.py.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from fastapi import params
from fastapi.dependencies.models import Dependant
from fastapi.routing import APIRoute
from starlette.datastructures import Headers
from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.auth import KEY_HEADER, RequireRole, Role, lookup
from app.errors import Forbidden, TooLarge, TooManyRequests, Unauthorized, error_response

ROUTE_KEY = "tracker.route_template"  # set in the scope: the path template of the route found
UNMATCHED = "<unmatched>"


def client_address(scope: Scope) -> str:
    """The peer's address (the proxy's, behind a reverse proxy)."""
    client = scope.get("client")
    return str(client[0]) if client else "unknown"


def required_role(dependant: Dependant) -> Role | None:
    """The role a route's dependencies require (the highest found), or None when it needs no key."""
    found = [d.call.role for d in dependant.dependencies if isinstance(d.call, RequireRole)]
    found += [r for d in dependant.dependencies if (r := required_role(d)) is not None]
    return max(found) if found else None


def takes_upload(route: APIRoute) -> bool:
    """True when the route reads a multipart form (a file upload)."""
    field = route.body_field
    return field is not None and isinstance(field.field_info, params.Form)


class RequestGuard:
    """ASGI middleware in front of ``routes`` (mounted under ``prefix``); see the module docstring."""

    def __init__(self, app: ASGIApp, prefix: str, routes: Sequence[APIRoute]) -> None:
        self.app = app
        self.prefix = prefix
        self._routes = [(route, required_role(route.dependant), takes_upload(route)) for route in routes]

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        svc = getattr(scope["app"].state, "svc", None) if "app" in scope else None
        if scope["type"] != "http" or svc is None:
            await self.app(scope, receive, send)
            return
        role, upload = self._route_needs(scope)
        refusal = self._check_key(svc, scope, role) if role is not None else None
        s = svc.settings
        limit = s.max_upload_bytes if upload else s.max_body_bytes
        length = Headers(scope=scope).get("content-length")
        routed = scope.get(ROUTE_KEY) not in (None, UNMATCHED)  # else the router's 404 reads nothing
        if refusal is None and routed and length is not None and length.isdigit() and int(length) > limit:
            refusal = _too_large(limit, upload)
        if refusal is not None:
            await error_response(refusal)(scope, receive, send)
            return
        await self._run_counted(scope, receive, send, limit, upload)

    def _route_needs(self, scope: Scope) -> tuple[Role | None, bool]:
        """(the role the matching route needs, whether it takes an upload); (None, False) if none."""
        path: str = scope["path"]
        if not path.startswith(self.prefix + "/"):
            return None, False
        # Match on a fresh scope with the prefix stripped: the routes as their routers declared them.
        probe = {"type": "http", "method": scope["method"], "path": path[len(self.prefix):], "root_path": ""}
        for route, role, upload in self._routes:
            if route.matches(probe)[0] == Match.FULL:
                scope[ROUTE_KEY] = self.prefix + route.path  # the metrics' label (app/metrics.py)
                return role, upload
        scope[ROUTE_KEY] = UNMATCHED  # no API route: no need to look again
        return None, False

    def _check_key(self, svc: Any, scope: Scope, role: Role) -> Exception | None:  # noqa: ANN401
        key = Headers(scope=scope).get(KEY_HEADER)
        if not key:
            return Unauthorized(f"missing API key (header {KEY_HEADER})")
        who = lookup(svc.db, key)
        if who is None:
            wait_s = svc.bad_keys.failed(client_address(scope))
            if wait_s > 0:
                return TooManyRequests(
                    f"too many unknown or revoked API keys from this address; retry in {wait_s:.0f} s",
                    retry_after_s=wait_s,
                )
            return Unauthorized(f"unknown or revoked API key (header {KEY_HEADER})")
        if who.role < role:
            return Forbidden(f"role {who.role.name} may not do this; needs {role.name}")
        return None

    async def _run_counted(
        self, scope: Scope, receive: Receive, send: Send, limit: int, upload: bool
    ) -> None:
        """Run the app, counting body bytes; past ``limit`` the app's answer is replaced by 413."""
        received = 0
        refused: TooLarge | None = None
        started = False

        async def receive_counted() -> Message:
            nonlocal received, refused
            if refused is not None:
                raise refused
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    refused = _too_large(limit, upload)
                    raise refused
            return message

        async def send_unless_refused(message: Message) -> None:
            nonlocal started
            if refused is not None:
                return  # whatever the app makes of the cut-off body, the answer is the 413
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, receive_counted, send_unless_refused)
        except Exception:
            if refused is None:
                raise
        if refused is not None and not started:
            await error_response(refused)(scope, receive, send)


def _too_large(limit: int, upload: bool) -> TooLarge:
    setting = "max_upload_bytes" if upload else "max_body_bytes"
    what = "an upload" if upload else "a request body"
    return TooLarge(
        f"{what} may have at most {limit} bytes (setting {setting})", limit_bytes=limit, setting=setting
    )
