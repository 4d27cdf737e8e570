"""WS /telemetry: angles, targets, commands and localizer estimates as JSON frames (≥ 50 Hz).

Authenticate with the ``X-API-Key`` header, or (browsers cannot set WebSocket headers) send
``{"key": "..."}`` as the first message within 5 s. The server answers ``{"type": "hello", ...}``
and then streams ``{"type": "frame", "t_s", "pan_deg", "tilt_deg", "pan_target_deg",
"tilt_target_deg", "pan_u_v", "tilt_u_v", "mode", "tracking", "source", "estimate_azimuth_deg",
"estimate_elevation_deg"}``. Close codes: 4401 no/unknown key, or the key was revoked while
streaming (at once, reason "API key revoked"), 4408 no key in time, 4429 too many bad keys from
this address (the reason says when to retry).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
from typing import Any

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from app.auth import KEY_HEADER, Principal, websocket_principal

router = APIRouter(tags=["telemetry"])
AUTH_TIMEOUT_S = 5.0


async def _receive_key(ws: WebSocket) -> str | None:
    try:
        text = await asyncio.wait_for(ws.receive_text(), timeout=AUTH_TIMEOUT_S)
    except TimeoutError:
        return None
    try:
        msg = json.loads(text)
    except ValueError:
        return None
    key = msg.get("key") if isinstance(msg, dict) else None
    return key if isinstance(key, str) else None


async def _drain_client(ws: WebSocket) -> None:
    """Read (and ignore) client messages so a disconnect is noticed."""
    while True:
        await ws.receive_text()


async def _authenticate(ws: WebSocket) -> Principal | None:
    """The client's principal; None after closing the socket with the reason."""
    key = ws.headers.get(KEY_HEADER) or await _receive_key(ws)
    who = websocket_principal(ws, key)
    if who is not None:
        return who
    if not key:
        await ws.close(code=4408, reason="no API key")
        return None
    address = ws.client.host if ws.client else "unknown"
    wait_s = ws.app.state.svc.bad_keys.failed(address)
    if wait_s > 0:
        await ws.close(code=4429, reason=f"too many bad API keys; retry in {wait_s:.0f} s")
    else:
        await ws.close(code=4401, reason="unknown or revoked API key")
    return None


@router.websocket("/telemetry")
async def telemetry(ws: WebSocket) -> None:
    await ws.accept()
    who = await _authenticate(ws)
    if who is None:
        return
    svc = ws.app.state.svc
    sub = svc.hub.subscribe(maxsize=256, key_id=who.key_id)
    reader = asyncio.create_task(_drain_client(ws))
    ended = asyncio.create_task(sub.ended.wait())
    sender: asyncio.Task[None] | None = None
    try:
        await ws.send_json(
            {
                "type": "hello",
                "name": who.name,
                "role": who.role.name,
                "rate_hz": svc.settings.telemetry_rate_hz,
            }
        )
        # Tasks for the life of the connection (not futures per frame): the sender streams, the
        # reader notices the client leaving, ``ended`` a revoked key; the first to end ends all.
        sender = asyncio.create_task(_send_frames(ws, sub))
        await asyncio.wait({reader, sender, ended}, return_when=asyncio.FIRST_COMPLETED)
        if ended.done():
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await sender
            await ws.close(code=4401, reason=sub.end_reason)
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        sub.close()
        for task in (ended, reader, sender):
            if task is not None:
                task.cancel()
                with contextlib.suppress(Exception, asyncio.CancelledError):
                    await task


async def _send_frames(ws: WebSocket, sub: Any) -> None:
    """Send each frame's JSON (encoded once by the hub for every client)."""
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        while True:
            frame = await sub.queue.get()
            text = getattr(frame, "text", None)
            await ws.send_text(text if isinstance(text, str) else json.dumps(frame, separators=(",", ":")))
