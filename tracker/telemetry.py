"""What the engine publishes: telemetry snapshots, its status, and subscriptions that drop the oldest."""

from __future__ import annotations

import asyncio
import threading
from collections import deque
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
    """Async iterator of snapshots; a slow consumer loses the oldest ones. ``close()`` to leave.

    Thread-safe: the engine's thread puts, a consumer on an event loop iterates (it is woken
    through ``call_soon_threadsafe``; the engine never waits for it).
    """

    def __init__(self, maxsize: int, on_close: Callable[[TelemetrySubscription], None]) -> None:
        self._on_close = on_close
        self._maxsize = max(1, maxsize)
        self._items: deque[TelemetrySnapshot | None] = deque()
        self._lock = threading.Lock()
        self._waiter: asyncio.Future[None] | None = None
        self._waiter_loop: asyncio.AbstractEventLoop | None = None
        self.dropped = 0
        self.closed = False

    def put(self, item: TelemetrySnapshot | None) -> None:
        """Publish (None ends the iteration); drops the oldest when full. Any thread."""
        with self._lock:
            if len(self._items) >= self._maxsize:
                self._items.popleft()
                self.dropped += 1
            self._items.append(item)
            waiter, loop = self._waiter, self._waiter_loop
            self._waiter = self._waiter_loop = None
        if waiter is not None and loop is not None:
            try:
                running = asyncio.get_running_loop()
            except RuntimeError:
                running = None
            if running is loop:
                _wake(waiter)
            else:
                try:
                    loop.call_soon_threadsafe(_wake, waiter)
                except RuntimeError:  # the consumer's loop is closed
                    pass

    def get_nowait(self) -> TelemetrySnapshot | None:
        """The oldest queued item; IndexError when there is none."""
        with self._lock:
            return self._items.popleft()

    def __aiter__(self) -> TelemetrySubscription:
        return self

    async def __anext__(self) -> TelemetrySnapshot:
        loop = asyncio.get_running_loop()
        while True:
            with self._lock:
                if self._items:
                    item = self._items.popleft()
                    break
                if self.closed:
                    raise StopAsyncIteration
                waiter = loop.create_future()
                self._waiter, self._waiter_loop = waiter, loop
            await waiter
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


def _wake(waiter: asyncio.Future[None]) -> None:
    if not waiter.done():
        waiter.set_result(None)
