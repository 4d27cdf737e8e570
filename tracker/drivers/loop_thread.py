"""An asyncio event loop of its own, in a daemon thread: a driver's clock that no web request,
upload or WebSocket viewer on the service's event loop can hold up (a PTZ camera's command
cycle, :mod:`tracker.drivers.visca`).

:meth:`LoopThread.run` awaits a coroutine on that loop from another event loop (cancelling the
caller cancels it there); :meth:`LoopThread.call` runs a plain function there and waits for it.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import threading
from collections.abc import Callable, Coroutine
from typing import Any, TypeVar

T = TypeVar("T")


class LoopThread:
    """An event loop running in its own daemon thread until :meth:`stop`."""

    def __init__(self, name: str) -> None:
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        try:
            self.loop.run_forever()
        finally:
            self.loop.close()

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def here(self) -> bool:
        """Whether the caller runs on this loop."""
        try:
            return asyncio.get_running_loop() is self.loop
        except RuntimeError:
            return False

    async def run(self, coro: Coroutine[Any, Any, T]) -> T:
        """Await ``coro`` on this loop (at once if already on it)."""
        if self.here():
            return await coro
        return await asyncio.wrap_future(asyncio.run_coroutine_threadsafe(coro, self.loop))

    def call(self, fn: Callable[[], T], timeout_s: float = 5.0) -> T:
        """Run ``fn()`` on this loop and return its result (from another thread)."""
        if self.here():
            return fn()
        done: concurrent.futures.Future[T] = concurrent.futures.Future()

        def go() -> None:
            try:
                done.set_result(fn())
            except BaseException as exc:  # handed to the caller
                done.set_exception(exc)

        self.loop.call_soon_threadsafe(go)
        return done.result(timeout_s)

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the loop (its pending tasks are dropped: close them first) and join the thread."""
        if self._thread.is_alive():
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._thread.join(timeout_s)
