"""Heavy work off the engine's event loop: a small pool of worker processes with a bounded queue.

The engine's loop runs in its own thread of the service; a compare or a fit in a thread would
share the interpreter lock with it (the numba kernels hold it for seconds), so heavy work runs in
``workers`` separate processes (spawned: the service has threads that a fork would copy
half-way). At most ``workers + queue`` requests are admitted at once and at most ``per_key`` of
them from one key; the next one gets 429 with a Retry-After from the recent mean duration.
A worker that dies (out of memory) costs its request a 503 and the pool is started again.
The workers run ``app.workers.WORKER_NICE`` steps nicer than the service.
"""

from __future__ import annotations

import asyncio
import multiprocessing
import os
import time
from collections import Counter
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from app.auth import Principal
from app.errors import TooManyRequests, Unavailable

T = TypeVar("T")


def _init_heavy_worker(effects: str) -> None:
    """A heavy worker's start: the site's effects, and background priority (like the job
    workers: on a busy machine the service's threads, and the loop, get the CPU first)."""
    from app.workers import WORKER_NICE, exit_with_parent

    exit_with_parent()
    load_site_effects(effects)
    try:
        os.nice(WORKER_NICE)
    except (AttributeError, OSError):
        pass


def worker_niceness() -> int:
    """This process's niceness (run in a worker by the tests)."""
    return os.nice(0)


def load_site_effects(effects: str) -> None:
    """A worker's start: the effects setting's plug-ins join its catalogue, as in the service
    (a spawned process imports the engine afresh; TRACKER_EFFECTS it reads by itself)."""
    from tracker.plant.effects import load_effect_modules

    load_effect_modules(effects, "effects setting")


class WorkPool:
    """Runs heavy functions in worker processes, a bounded number at a time."""

    def __init__(
        self,
        workers: int = 1,
        queue: int = 4,
        per_key: int = 2,
        effects: str = "",
        observe: Callable[[str, str, float], None] | None = None,
    ) -> None:
        """``observe(kind, outcome, duration_s)`` is told of each request's end (the metrics):
        kind is the function's name, outcome ok, error or lost (its worker died)."""
        self.observe = observe
        self.workers, self.queue, self.per_key = workers, queue, per_key
        self.effects = effects  # the site's effect plug-ins: each spawned worker loads them too
        self._executor: ProcessPoolExecutor | None = None
        self._admitted = 0
        self._by_key: Counter[int] = Counter()
        self._mean_s = 1.0  # running mean of recent durations: the Retry-After

    @property
    def admitted(self) -> int:
        """Requests running or waiting now."""
        return self._admitted

    async def run(self, who: Principal, fn: Callable[..., T], *args: Any) -> T:  # noqa: ANN401
        """``fn(*args)`` in a worker process for ``who``; TooManyRequests (429) when over a cap."""
        if self._by_key[who.key_id] >= self.per_key:
            raise TooManyRequests(
                f"key {who.name!r} already has {self._by_key[who.key_id]} heavy request(s) running or "
                f"waiting (cap {self.per_key}, setting heavy_per_key); retry when one is done",
                retry_after_s=self._mean_s,
            )
        capacity = self.workers + self.queue
        if self._admitted >= capacity:
            raise TooManyRequests(
                f"the service is busy with {self._admitted} heavy requests (cap {capacity}, settings "
                "heavy_workers + heavy_queue); retry later",
                retry_after_s=self._mean_s * (1 + self.queue / self.workers),
            )
        loop = asyncio.get_running_loop()
        self._admitted += 1
        self._by_key[who.key_id] += 1
        t0 = time.monotonic()

        def done(future: Future[T]) -> None:  # runs when the work ends, even if the request is gone
            loop.call_soon_threadsafe(self._release, who.key_id, time.monotonic() - t0)
            if self.observe is not None:
                error = None if future.cancelled() else future.exception()
                outcome = ("cancelled" if future.cancelled() else "ok" if error is None
                           else "lost" if isinstance(error, BrokenProcessPool) else "error")
                self.observe(getattr(fn, "__name__", "work"), outcome, time.monotonic() - t0)

        try:
            future = self._pool().submit(fn, *args)
        except BrokenProcessPool:
            self._release(who.key_id, None)
            self._restart()
            raise Unavailable("the worker pool had stopped; it is starting again, retry") from None
        future.add_done_callback(done)
        try:
            return await asyncio.wrap_future(future)
        except BrokenProcessPool:
            self._restart()
            raise Unavailable(
                "a worker process died during this request (out of memory?); the pool is starting again"
            ) from None

    def warm(self, fn: Callable[[], object]) -> None:
        """Start the workers now with ``fn`` (imports), so the first request does not wait for them."""
        self._pool().submit(fn)

    def _release(self, key_id: int, duration_s: float | None) -> None:
        self._admitted -= 1
        self._by_key[key_id] -= 1
        if self._by_key[key_id] <= 0:
            del self._by_key[key_id]
        if duration_s is not None:
            self._mean_s = 0.7 * self._mean_s + 0.3 * duration_s

    def _pool(self) -> ProcessPoolExecutor:
        if self._executor is None:
            spawn = multiprocessing.get_context("spawn")
            self._executor = ProcessPoolExecutor(
                self.workers, mp_context=spawn, initializer=_init_heavy_worker, initargs=(self.effects,)
            )
        return self._executor

    def _restart(self) -> None:
        old, self._executor = self._executor, None
        if old is not None:
            old.shutdown(wait=False, cancel_futures=True)

    def close(self) -> None:
        """Stop the workers at once (waiting work is dropped, running work ends with its process)."""
        if self._executor is None:
            return
        # The executor has no public way to stop a running task; its processes are the only handle.
        processes = list((getattr(self._executor, "_processes", None) or {}).values())
        self._executor.shutdown(wait=False, cancel_futures=True)
        self._executor = None
        for process in processes:
            process.terminate()
