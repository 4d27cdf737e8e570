"""The 3D view through the console (same origin, same keys): POST /view/session, GET /view/
(viser's client) and WS /view (relayed to viser's loopback port). See app/view_proxy.py.

Refusals come before anything reaches viser: 401 without a key or session (403 from another
origin, 429 while the address is blocked for bad keys, 503 when the view is off). A WebSocket is
refused at the handshake with that HTTP status and JSON body (or, on a server that cannot send
one, closed before it is accepted); a key revoked while viewing closes the view with 4401.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response, WebSocket
from fastapi.responses import FileResponse
from starlette.datastructures import Headers

from app.auth import KEY_HEADER, Viewer
from app.errors import (
    Forbidden,
    NotFound,
    TooManyRequests,
    Unauthorized,
    Unavailable,
    error_response,
)
from app.guard import client_address
from app.service import Service, Svc
from app.view_proxy import COOKIE, VIEW_PATH, ViewAccess, client_build_dir, relay, same_origin, view_access

router = APIRouter(tags=["view"])
NOT_RUNNING = "the 3D view is disabled (TRACKER_VIEWER_ENABLED) or failed to start"


@router.post("/view/session", summary="Open a 3D-view session for this key (sets the view cookie)")
async def open_view_session(request: Request, response: Response, svc: Svc, who: Viewer) -> dict[str, Any]:
    """The console calls this with its key before showing the view: browsers cannot send the
    key header from an iframe or a WebSocket, so the answer sets an HttpOnly cookie (path
    /api/v1/view, SameSite=Strict, Secure over https) naming a session bound to this key."""
    if svc.viewer is None:
        raise Unavailable(NOT_RUNNING)
    sessions = svc.view_sessions
    token = sessions.issue(who.key_id)
    response.set_cookie(COOKIE, token, max_age=int(sessions.ttl_s), path=VIEW_PATH, httponly=True,
                        samesite="strict", secure=request.url.scheme == "https")
    return {"url": VIEW_PATH + "/", "expires_in_s": sessions.ttl_s}


def refusal_for(svc: Service, access: ViewAccess, headers: Headers, address: str) -> Exception | None:
    """Why a view request is refused (None: it may go through)."""
    if access.via_cookie and not same_origin(headers):
        return Forbidden("the 3D view is served to pages of this console only (Origin differs)")
    if access.who is None:
        if access.bad_key:
            wait_s = svc.bad_keys.failed(address)
            if wait_s > 0:
                return TooManyRequests(
                    f"too many unknown or revoked API keys from this address; retry in {wait_s:.0f} s",
                    retry_after_s=wait_s,
                )
            return Unauthorized(f"unknown or revoked API key (header {KEY_HEADER})")
        return Unauthorized(
            f"no API key (header {KEY_HEADER}) and no view session (POST {VIEW_PATH}/session)"
        )
    if svc.viewer is None:
        return Unavailable(NOT_RUNNING)
    return None


@router.get("/view/{path:path}", include_in_schema=False)
async def view_client(path: str, request: Request, svc: Svc) -> FileResponse:
    """viser's client files (its build is one index.html)."""
    access = view_access(svc.db, svc.view_sessions, request.headers)
    refusal = refusal_for(svc, access, request.headers, client_address(request.scope))
    if refusal is not None:
        raise refusal
    segments = [s for s in path.split("/") if s and s != "."]
    root = client_build_dir()
    target = root.joinpath(*segments) if segments else root / "index.html"
    if ".." in segments or not target.is_file():
        raise NotFound(f"no file {path!r} in the 3D view's client")
    return FileResponse(target)


@router.websocket("/view")
async def view_socket(ws: WebSocket) -> None:
    """viser's WebSocket, relayed to its loopback port once the key or session is checked."""
    svc: Service = ws.app.state.svc
    access = view_access(svc.db, svc.view_sessions, ws.headers)
    refusal = refusal_for(svc, access, ws.headers, client_address(ws.scope))
    if refusal is not None or access.who is None:
        await _deny(ws, refusal or Unauthorized("no key"))
        return
    host = svc.viewer.host if svc.viewer.host not in {"0.0.0.0", "::", ""} else "127.0.0.1"
    with svc.view_sessions.open_view(access.who.key_id) as ended:
        await relay(ws, f"ws://{host}:{svc.viewer.port}", ended)


async def _deny(ws: WebSocket, exc: Exception) -> None:
    """Refuse the handshake with the error's status and JSON body; else close before accepting."""
    try:
        await ws.send_denial_response(error_response(exc))
    except RuntimeError:  # the server lacks the denial-response extension
        await ws.close(code=4401 if isinstance(exc, Unauthorized) else 4403)
