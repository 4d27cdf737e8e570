"""Jobs in a bounded pool of worker processes, so a long experiment never holds the service's
interpreter (and its GIL) while the control loop's thread needs it; with progress and cancel
(:mod:`app.work` runs the request-scoped heavy work, which needs neither).

:class:`WorkerPool` wraps a ``ProcessPoolExecutor`` (spawned interpreters: the service has
threads, and forking a threaded process is unsafe). ``run(fn, *args)`` awaits a module-level
function on plain, picklable arguments (JSON-like values, CSV text; never the database, which
stays in the service). ``submit_job`` runs ``fn(progress, cancel, *args)`` for a job: progress
comes back through a multiprocessing queue (read by a thread of the service, written to the
database), cancel goes out through a flag per job in shared memory. Workers run 5 steps nicer
than the service, so on a busy machine the loop and the web side get the CPU first.
"""

from __future__ import annotations

import asyncio
import multiprocessing
import os
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from multiprocessing.sharedctypes import SynchronizedArray
from typing import Any, TypeVar

T = TypeVar("T")
JOB_SLOTS = 64
WORKER_NICE = 5  # the workers' niceness above the service's
PARENT_CHECK_S = 1.0  # how often a worker looks whether the service that spawned it is still there
ProgressFn = Callable[[int, float, str], None]

# In a worker: the queue and flags the pool handed it at start-up.
_progress_queue: Any = None
_cancel_flags: Any = None


def exit_with_parent(every_s: float = PARENT_CHECK_S) -> None:
    """A worker's start: end this process once the service that spawned it is gone. A killed
    service cannot shut its pools down; orphaned, a worker kept its memory and the
    multiprocessing resource tracker alive, and the tracker then never unlinked the shared
    memory of the loop's process (loop_process = true) either."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(every_s)
        os._exit(0)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _init_worker(progress_queue: Any, cancel_flags: Any, effects: str) -> None:
    global _progress_queue, _cancel_flags
    exit_with_parent()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # see tracker.cli
    if effects:  # the site's effect plug-ins, as in the service (a rig config may name them)
        from app.work import load_site_effects

        load_site_effects(effects)
    try:  # background work: on a busy machine the service's own threads come first
        os.nice(WORKER_NICE)
    except (AttributeError, OSError):
        pass
    _progress_queue, _cancel_flags = progress_queue, cancel_flags


class WorkerProgress:
    """A job's ``progress(fraction, message)`` in a worker: at most ten reports a second."""

    def __init__(self, job_id: int, min_interval_s: float = 0.1) -> None:
        self._id, self._min, self._last = job_id, min_interval_s, 0.0
        self.fraction = 0.0

    def __call__(self, fraction: float, message: str = "") -> None:
        self.fraction = min(1.0, max(0.0, float(fraction)))
        now = time.monotonic()
        if now - self._last >= self._min or self.fraction >= 1.0:
            self._last = now
            if _progress_queue is not None:
                _progress_queue.put((self._id, self.fraction, str(message)[:200]))


class WorkerCancel:
    """A job's cancel token in a worker: call it (or ``is_set()``) to ask whether to stop."""

    def __init__(self, slot: int) -> None:
        self._slot = slot

    def is_set(self) -> bool:
        return bool(_cancel_flags is not None and _cancel_flags[self._slot])

    def __call__(self) -> bool:
        return self.is_set()


def _job_entry(
    fn: Callable[..., dict[str, Any]], job_id: int, slot: int, args: tuple[Any, ...]
) -> dict[str, Any]:
    return fn(WorkerProgress(job_id), WorkerCancel(slot), *args)


class WorkerPool:
    """The service's worker processes (see the module docstring)."""

    def __init__(self, max_workers: int, on_progress: ProgressFn | None = None, effects: str = "") -> None:
        ctx = multiprocessing.get_context("spawn")
        self._progress: Any = ctx.Queue()
        self._cancel: SynchronizedArray[int] | list[int] = ctx.Array("b", JOB_SLOTS)
        self._executor: ProcessPoolExecutor | None = ProcessPoolExecutor(
            max_workers, mp_context=ctx, initializer=_init_worker,
            initargs=(self._progress, self._cancel, effects))
        self._free = list(range(JOB_SLOTS))
        self._lock = threading.Lock()
        self._on_progress = on_progress
        self._closing = threading.Event()
        self._pump = threading.Thread(target=self._pump_progress, name="job-progress", daemon=True)
        self._pump.start()

    async def run(self, fn: Callable[..., T], *args: Any) -> T:
        """``fn(*args)`` in a worker; its exceptions are raised here."""
        return await asyncio.get_running_loop().run_in_executor(self._running(), fn, *args)

    def submit_job(
        self, fn: Callable[..., dict[str, Any]], job_id: int, *args: Any
    ) -> tuple[int, Future[Any]]:
        """Start ``fn(progress, cancel, *args)``; returns (its cancel slot, its future)."""
        with self._lock:
            if not self._free:
                raise RuntimeError(f"more than {JOB_SLOTS} jobs at once")
            slot = self._free.pop()
        self._cancel[slot] = 0
        future = self._running().submit(_job_entry, fn, job_id, slot, args)
        future.add_done_callback(lambda _: self._release(slot))
        return slot, future

    def _running(self) -> ProcessPoolExecutor:
        if self._executor is None:
            raise RuntimeError("the worker pool is shut down")
        return self._executor

    def cancel(self, slot: int) -> None:
        self._cancel[slot] = 1

    def _release(self, slot: int) -> None:
        with self._lock:
            self._free.append(slot)

    def _pump_progress(self) -> None:
        while not self._closing.is_set():
            try:
                job_id, fraction, message = self._progress.get(timeout=0.25)
            except queue.Empty:
                continue
            except (EOFError, OSError):
                return
            if self._on_progress is not None:
                self._on_progress(job_id, fraction, message)

    def shutdown(self) -> None:
        """Ask running jobs to stop, then stop the workers."""
        for slot in range(JOB_SLOTS):
            self._cancel[slot] = 1
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
        # The executor keeps the queue and the flags (its workers' initargs): let go of it, so
        # that their 4 semaphores are unlinked when the queue and flags go, here. Left to the
        # process's exit they never were: uvicorn ends the service by re-raising its SIGTERM,
        # which skips multiprocessing's exit handlers, and the resource tracker reported "4
        # leaked semaphore objects" at every shutdown (and unlinked them itself).
        self._executor = None  # (the queue and the flags go below)
        self._closing.set()
        self._pump.join(1.0)
        self._progress.close()
        self._progress.join_thread()
        self._progress, self._cancel = None, [1] * JOB_SLOTS  # the last references
