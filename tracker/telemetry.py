"""What the engine publishes: telemetry snapshots, its status, and subscriptions that drop the oldest."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class TelemetrySnapshot:
    """One published sample (angles are encoder readings, rad; commands in V)."""

    t_s: float
    pan_rad: float
    tilt_rad: float
    pan_target_rad: float
    tilt_target_rad: float
    pan_u_v: float
    tilt_u_v: float
    mode: str
    tracking: bool
    source: str | None
    estimate_azimuth_rad: float | None = None
    estimate_elevation_rad: float | None = None


@dataclass(frozen=True, slots=True)
class EngineStatus:
    """The engine's state right now."""

    t_s: float
    pan_rad: float
    tilt_rad: float
    pan_target_rad: float
    tilt_target_rad: float
    mode: str
    tracking: bool
    faults: tuple[str, ...]
    active_talker: str | None


class TelemetrySubscription:
    """Async iterator of snapshots; a slow consumer loses the oldest ones. ``close()`` to leave."""

    def __init__(self, maxsize: int, on_close: Callable[[TelemetrySubscription], None]) -> None:
        self._on_close = on_close
        self._queue: asyncio.Queue[TelemetrySnapshot | None] = asyncio.Queue(maxsize=max(1, maxsize))
        self.dropped = 0
        self.closed = False

    def put(self, item: TelemetrySnapshot | None) -> None:
        """Publish (None ends the iteration); drops the oldest when full."""
        if self._queue.full():
            self._queue.get_nowait()
            self.dropped += 1
        self._queue.put_nowait(item)

    def __aiter__(self) -> TelemetrySubscription:
        return self

    async def __anext__(self) -> TelemetrySnapshot:
        if self.closed and self._queue.empty():
            raise StopAsyncIteration
        item = await self._queue.get()
        if item is None:
            self.closed = True
            raise StopAsyncIteration
        return item

    def close(self) -> None:
        """Stop receiving; a pending iteration ends."""
        if not self.closed:
            self._on_close(self)
            self.closed = True
            self.put(None)
