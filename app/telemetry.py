"""Telemetry fan-out: one engine subscription, decimated to a frame rate, copied to many WebSockets.

The engine publishes a snapshot per control tick (up to 1 kHz). The hub keeps the latest
snapshot (the 3D view and status read it) and, whenever ``1/rate_hz`` of engine time has passed,
encodes one JSON frame (degrees) once and puts it in every client's queue. A slow client loses
its oldest frames; it never slows the engine or the other clients.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
from collections.abc import AsyncIterator
from typing import Any

from tracker.telemetry import TelemetrySnapshot as Snapshot

log = logging.getLogger("app.telemetry")


def _deg(x: float | None) -> float | None:
    if x is None or not math.isfinite(x):
        return None
    return round(math.degrees(x), 4)


def frame_of(s: Snapshot) -> dict[str, Any]:
    """The JSON frame of a snapshot (angles in degrees, commands in volts)."""
    return {
        "type": "frame",
        "t_s": round(float(s.t_s), 4),
        "pan_deg": _deg(s.pan_rad),
        "tilt_deg": _deg(s.tilt_rad),
        "pan_target_deg": _deg(s.pan_target_rad),
        "tilt_target_deg": _deg(s.tilt_target_rad),
        "pan_u_v": round(float(s.pan_u_v), 4),
        "tilt_u_v": round(float(s.tilt_u_v), 4),
        "mode": s.mode,
        "tracking": bool(s.tracking),
        "source": s.source,
        "estimate_azimuth_deg": _deg(s.estimate_azimuth_rad),
        "estimate_elevation_deg": _deg(s.estimate_elevation_rad),
    }


class Frame(dict[str, Any]):
    """A frame (a dict, see :func:`frame_of`) with its JSON text, encoded once for all clients."""

    __slots__ = ("text",)

    def __init__(self, fields: dict[str, Any]) -> None:
        super().__init__(fields)
        self.text = json.dumps(fields, separators=(",", ":"))


class Subscription:
    """One client's bounded queue of frames; ``ended`` is set (with ``end_reason``) to close it."""

    def __init__(self, hub: TelemetryHub, maxsize: int, key_id: int | None = None) -> None:
        self._hub = hub
        self.key_id = key_id
        self.queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=maxsize)
        self.dropped = 0
        self.ended = asyncio.Event()
        self.end_reason = ""

    def offer(self, frame: dict[str, Any]) -> None:
        if self.queue.full():
            with contextlib.suppress(asyncio.QueueEmpty):
                self.queue.get_nowait()
                self.dropped += 1
                self._hub.frames_dropped += 1
        self.queue.put_nowait(frame)

    async def __aiter__(self) -> AsyncIterator[dict[str, Any]]:
        while True:
            yield await self.queue.get()

    def close(self) -> None:
        self._hub._subs.discard(self)


class TelemetryHub:
    """Reads the engine's snapshots and fans frames out to any number of subscribers."""

    def __init__(self, rate_hz: float = 100.0) -> None:
        self.period_s = 1.0 / rate_hz
        self.latest: Snapshot | None = None
        self.latest_frame: dict[str, Any] | None = None
        self.frames_sent = 0
        self.frames_dropped = 0  # frames a slow client's full queue lost, all clients together
        self._subs: set[Subscription] = set()
        self._last_t_s = -math.inf
        self._task: asyncio.Task[None] | None = None

    @property
    def clients(self) -> int:
        return len(self._subs)

    def subscribe(self, maxsize: int = 256, key_id: int | None = None) -> Subscription:
        """A new subscriber (for the API key ``key_id``); call ``close()`` when done."""
        sub = Subscription(self, maxsize, key_id)
        self._subs.add(sub)
        return sub

    def disconnect_key(self, key_id: int, reason: str) -> int:
        """End every subscription of ``key_id`` (its key was revoked); how many there were."""
        subs = [s for s in self._subs if s.key_id == key_id]
        for sub in subs:
            sub.end_reason = reason
            sub.ended.set()
            sub.close()
        return len(subs)

    def publish(self, snap: Snapshot) -> None:
        """Take one engine snapshot; emit a frame when a frame period of engine time has passed."""
        self.latest = snap
        if snap.t_s < self._last_t_s:  # engine restarted its clock
            self._last_t_s = -math.inf
        if snap.t_s - self._last_t_s < self.period_s - 1e-9:
            return
        self._last_t_s = snap.t_s
        frame = Frame(frame_of(snap))
        self.latest_frame = frame
        self.frames_sent += 1
        for sub in list(self._subs):
            sub.offer(frame)

    def start(self, engine: Any) -> None:
        """Follow ``engine.subscribe()`` in a task until :meth:`stop`."""
        self._task = asyncio.create_task(self._follow(engine), name="telemetry-hub")

    async def _follow(self, engine: Any) -> None:
        stream = engine.subscribe(maxsize=1024)
        try:
            async for snap in stream:
                self.publish(snap)
        except asyncio.CancelledError:
            raise
        except Exception:  # a broken stream must not take the service down silently
            log.exception("telemetry stream from the engine failed")
        finally:
            close = getattr(stream, "close", None)
            if close is not None:
                close()

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
