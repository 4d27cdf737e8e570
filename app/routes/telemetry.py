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
    try:
        await ws.send_json(
            {
                "type": "hello",
                "name": who.name,
                "role": who.role.name,
                "rate_hz": svc.settings.telemetry_rate_hz,
            }
        )
        while True:
            get = asyncio.ensure_future(sub.queue.get())
            done, _ = await asyncio.wait({get, reader, ended}, return_when=asyncio.FIRST_COMPLETED)
            if reader in done or ended in done:
                get.cancel()
                break
            frame = get.result()
            text = getattr(frame, "text", None)  # encoded once by the hub for every client
            await ws.send_text(text if isinstance(text, str) else json.dumps(frame, separators=(",", ":")))
        if ended.done():
            await ws.close(code=4401, reason=sub.end_reason)
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        sub.close()
        ended.cancel()
        reader.cancel()
        with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, RuntimeError, Exception):
            await reader
