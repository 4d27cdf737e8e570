"""The 3D view through the console: who may see it (an API key, or a view session cookie the
console obtains with its key), viser's client files, and the WebSocket relayed to viser's
loopback port.

viser has no authentication and listens on its own port; a browser behind the TLS proxy cannot
reach ``http://host:8081`` (mixed content), and anyone who could reach it would see the room. So
the service serves viser's client itself under ``/api/v1/view/`` and relays its WebSocket
(``/api/v1/view``, where viser's client connects: the page's address without the trailing
slash) to ``ws://127.0.0.1:<viewer port>``, after the key check and before any byte reaches
viser. A browser page cannot put a header on an iframe or a WebSocket, so the console first calls
``POST /api/v1/view/session`` with its key; the answer sets an HttpOnly, SameSite=Strict cookie
scoped to ``/api/v1/view`` that names a random session bound to that key: revoking the key ends
the session and closes its views.
"""

from __future__ import annotations

import asyncio
import contextlib
import secrets
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from starlette.datastructures import Headers
from starlette.websockets import WebSocket, WebSocketDisconnect

from app.auth import KEY_HEADER, Principal, Role, lookup
from app.db import Database

COOKIE = "3dat_view"
VIEW_PATH = "/api/v1/view"
SESSION_TTL_S = 12 * 3600.0
MAX_SESSIONS = 1000
# viser sends whole meshes and point clouds in one message; its own server allows 50 MB.
MAX_MESSAGE_BYTES = 50 * 1024 * 1024


def client_build_dir() -> Path:
    """viser's built client (one self-contained index.html), where viser serves it from."""
    import viser

    return Path(viser.__file__).resolve().parent / "client" / "build"


@dataclass(frozen=True, slots=True)
class ViewSession:
    key_id: int
    expires_s: float


class ViewSessions:
    """Random view-session ids bound to API keys, held in memory (a restart signs views out;
    the console asks for a new session when it loads the view), and the open views of each key
    (so that revoking a key closes them at once)."""

    def __init__(self, ttl_s: float = SESSION_TTL_S, max_sessions: int = MAX_SESSIONS) -> None:
        self.ttl_s = ttl_s
        self.max_sessions = max_sessions
        self._sessions: dict[str, ViewSession] = {}
        self._open: dict[int, set[asyncio.Event]] = {}

    @property
    def open_views(self) -> int:
        return sum(len(v) for v in self._open.values())

    @contextlib.contextmanager
    def open_view(self, key_id: int) -> Iterator[asyncio.Event]:
        """For the life of one relayed view: an event set when ``key_id`` is revoked."""
        ended = asyncio.Event()
        self._open.setdefault(key_id, set()).add(ended)
        try:
            yield ended
        finally:
            self._open.get(key_id, set()).discard(ended)

    def end_key(self, key_id: int) -> int:
        """Forget ``key_id``'s sessions and end its open views (it was revoked); how many views."""
        self._sessions = {t: s for t, s in self._sessions.items() if s.key_id != key_id}
        views = self._open.pop(key_id, set())
        for ended in views:
            ended.set()
        return len(views)

    def issue(self, key_id: int) -> str:
        """A new session for ``key_id``; the oldest is dropped past ``max_sessions``."""
        now = time.monotonic()
        self._sessions = {t: s for t, s in self._sessions.items() if s.expires_s > now}
        while len(self._sessions) >= self.max_sessions:
            self._sessions.pop(next(iter(self._sessions)))
        token = secrets.token_urlsafe(32)
        self._sessions[token] = ViewSession(key_id, now + self.ttl_s)
        return token

    def key_id(self, token: str | None) -> int | None:
        """The key a live session belongs to; None when unknown or expired."""
        session = self._sessions.get(token or "")
        if session is None:
            return None
        if session.expires_s <= time.monotonic():
            self._sessions.pop(token or "", None)
            return None
        return session.key_id


def _cookie(headers: Headers, name: str) -> str | None:
    for part in headers.get("cookie", "").split(";"):
        key, _, value = part.strip().partition("=")
        if key == name:
            return value
    return None


@dataclass(frozen=True, slots=True)
class ViewAccess:
    """Who asks for the view (None: refused), and whether a bad API key was offered (which
    counts toward the address's back-off; a stale session cookie does not)."""

    who: Principal | None
    bad_key: bool
    via_cookie: bool


def view_access(db: Database, sessions: ViewSessions, headers: Headers) -> ViewAccess:
    """A viewer or better, from the ``X-API-Key`` header or the view-session cookie."""
    key = headers.get(KEY_HEADER)
    if key:
        who = lookup(db, key)
        return ViewAccess(who if who is not None and who.role >= Role.viewer else None, who is None, False)
    key_id = sessions.key_id(_cookie(headers, COOKIE))
    if key_id is None:
        return ViewAccess(None, False, True)
    rec = next((k for k in db.list_keys() if k.id == key_id), None)
    if rec is None or rec.revoked:
        return ViewAccess(None, False, True)
    return ViewAccess(Principal(rec.id, rec.name, Role.parse(rec.role)), False, True)


def same_origin(headers: Headers) -> bool:
    """True when a browser's Origin (if any) is the host it asked: a page elsewhere cannot
    ride the session cookie into a WebSocket."""
    origin = headers.get("origin")
    if origin is None:
        return True
    host = headers.get("host", "")
    return origin.split("://", 1)[-1].rstrip("/") == host


async def relay(ws: WebSocket, upstream_url: str, ended: asyncio.Event) -> None:
    """Accept ``ws`` with viser's subprotocol and relay messages both ways until either side
    closes or ``ended`` is set (the key was revoked: close 4401)."""
    from websockets.asyncio.client import connect
    from websockets.exceptions import ConnectionClosed, InvalidHandshake

    offered = [p for p in ws.scope.get("subprotocols", []) if p.startswith("viser-v")]
    try:
        upstream = await connect(
            upstream_url,
            subprotocols=offered or None,
            max_size=MAX_MESSAGE_BYTES,
            compression=None,
            open_timeout=5.0,
        )
    except (OSError, InvalidHandshake, TimeoutError):
        await ws.close(code=1011, reason="the 3D view is not running")
        return
    async with upstream:
        await ws.accept(subprotocol=upstream.subprotocol)

        async def downstream() -> None:
            async for data in upstream:
                if isinstance(data, bytes):
                    await ws.send_bytes(data)
                else:
                    await ws.send_text(data)

        async def upstream_from_client() -> None:
            while True:
                message = await ws.receive()
                if message["type"] == "websocket.disconnect":
                    return
                data = message.get("bytes")
                await upstream.send(data if data is not None else message.get("text", ""))

        tasks = [
            asyncio.create_task(downstream()),
            asyncio.create_task(upstream_from_client()),
            asyncio.create_task(ended.wait()),
        ]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            for task in tasks:
                with contextlib.suppress(asyncio.CancelledError, ConnectionClosed, WebSocketDisconnect,
                                         RuntimeError):
                    await task
        code, reason = (4401, "API key revoked") if ended.is_set() else _close_of(upstream)
        with contextlib.suppress(RuntimeError, WebSocketDisconnect):
            await ws.close(code=code, reason=reason)


def _close_of(upstream: Any) -> tuple[int, str]:  # noqa: ANN401 - a websockets connection
    """The close code and reason viser sent (1000 when it just went away)."""
    code = getattr(upstream, "close_code", None)
    if code is None or code in (1005, 1006, 1015):  # none sent, abnormal, TLS: not sendable
        return 1000, ""
    return int(code), str(getattr(upstream, "close_reason", "") or "")
