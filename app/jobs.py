"""Long jobs (friction-ID) in the worker processes (:mod:`app.workers`): progress and cancel.

A job's state lives in the database (queued → running → done | failed | cancelled), so any
client can poll it. The job function is a module-level function called in a worker as
``fn(progress, cancel, *args)``: ``progress(fraction, message)`` reaches the database through
the pool's queue; ``cancel`` works both as a callable (``cancel() -> bool``) and as an event
(``cancel.is_set()``), set from here through shared memory.

A job that must drive what lives on the service's event loop (the PTZ camera's link: the
speed-table identification) runs there instead, :meth:`JobRunner.start_local`, as an async
function ``fn(progress, cancel)`` with the same state, progress, cancel and cap.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Awaitable, Callable
from typing import Any

from app.db import Database
from app.errors import NotFound, TooManyRequests
from app.workers import WorkerCancel as CancelToken
from app.workers import WorkerPool
from app.workers import WorkerProgress as Progress
from tracker.errors import JobCancelled, TrackerError

log = logging.getLogger("app.jobs")

JobFn = Callable[..., dict[str, Any]]
LocalJobFn = Callable[[Callable[[float, str], None], Callable[[], bool]], Awaitable[dict[str, Any]]]


class JobRunner:
    """Starts jobs in the worker pool and keeps their cancel slots."""

    def __init__(
        self,
        db: Database,
        pool: WorkerPool,
        max_running: int = 2,
        observe: Callable[[str, str, float], None] | None = None,
    ) -> None:
        """``observe(kind, outcome, duration_s)`` is told of every job that ends (the metrics)."""
        self.db = db
        self.observe = observe
        self.pool = pool
        self.max_running = max_running
        self._slots: dict[int, int] = {}
        self._cancelled: set[int] = set()
        self._tasks: dict[int, asyncio.Task[None]] = {}

    def _check_room(self) -> None:
        """TooManyRequests (429) when ``max_running`` jobs are already running."""
        if len(self._tasks) >= self.max_running:
            raise TooManyRequests(
                f"{len(self._tasks)} jobs are running (cap {self.max_running}, setting max_running_jobs); "
                "wait for one to finish or cancel it",
                retry_after_s=5.0,
            )

    def start(self, kind: str, params: dict[str, Any], fn: JobFn, *args: Any) -> int:
        """Record the job and start ``fn(progress, cancel, *args)`` in a worker; returns its id.
        TooManyRequests (429) when ``max_running`` jobs are already running."""
        self._check_room()
        job_id = self.db.add_job(kind, params)
        self._tasks[job_id] = asyncio.create_task(self._run(job_id, kind, fn, args), name=f"job-{job_id}")
        return job_id

    def start_local(self, kind: str, params: dict[str, Any], fn: LocalJobFn) -> int:
        """Record the job and run ``await fn(progress, cancel)`` on this event loop (see the module
        docstring); returns its id. TooManyRequests (429) as :meth:`start`."""
        self._check_room()
        job_id = self.db.add_job(kind, params)

        def progress(fraction: float, message: str) -> None:
            if job_id not in self._cancelled:
                self.db.update_job(job_id, progress=fraction, message=message)

        def work(_job_id: int) -> Awaitable[dict[str, Any]]:
            return fn(progress, lambda: job_id in self._cancelled)

        self._tasks[job_id] = asyncio.create_task(self._run(job_id, kind, work, None), name=f"job-{job_id}")
        return job_id

    def progress(self, job_id: int, fraction: float, message: str) -> None:
        """A progress report from a worker (the pool's thread calls this)."""
        if job_id in self._slots and job_id not in self._cancelled:
            self.db.update_job(job_id, progress=fraction, message=message)

    async def _run(self, job_id: int, kind: str, fn: Callable[..., Any], args: tuple[Any, ...] | None,
                   ) -> None:
        """``args`` None: ``fn(job_id)`` is a coroutine run here (start_local), else a worker's job."""
        self.db.update_job(job_id, state="running")
        t0 = time.monotonic()
        try:
            if args is None:
                result = await fn(job_id)
            else:
                slot, future = self.pool.submit_job(fn, job_id, *args)
                self._slots[job_id] = slot
                if job_id in self._cancelled:  # cancelled before it was handed to the pool
                    self.pool.cancel(slot)
                result = await asyncio.wrap_future(future)
        except JobCancelled:
            self.db.update_job(job_id, state="cancelled", message="cancelled")
        except TrackerError as exc:
            self.db.update_job(job_id, state="failed", message=str(exc)[:500])
        except Exception as exc:  # a job failing must not take the service with it
            log.exception("job %d failed", job_id)
            self.db.update_job(
                job_id, state="failed", message=f"internal error: {type(exc).__name__}: {exc}"[:500]
            )
        else:
            if job_id in self._cancelled:
                self.db.update_job(job_id, state="cancelled", message="cancelled")
            else:
                self.db.update_job(job_id, state="done", progress=1.0, message="done", result=result)
        finally:
            if self.observe is not None:
                job = self.db.get_job(job_id)
                state = str(job["state"]) if job else ""
                outcome = state if state in {"done", "failed", "cancelled"} else "interrupted"
                self.observe(kind, outcome, time.monotonic() - t0)
            self._slots.pop(job_id, None)
            self._cancelled.discard(job_id)
            self._tasks.pop(job_id, None)

    def cancel(self, job_id: int) -> dict[str, Any]:
        """Ask a job to stop; NotFound when unknown. Returns its record."""
        job = self.db.get_job(job_id)
        if job is None:
            raise NotFound(f"no job {job_id}")
        if job_id in self._tasks:
            self._cancelled.add(job_id)
            slot = self._slots.get(job_id)
            if slot is not None:
                self.pool.cancel(slot)
            self.db.update_job(job_id, message="cancelling")
        return self.db.get_job(job_id) or job

    async def wait(self, job_id: int) -> None:
        task = self._tasks.get(job_id)
        if task is not None:
            await asyncio.shield(task)

    async def shutdown(self) -> None:
        self._cancelled.update(self._tasks)  # local jobs see it at their next step
        for job_id, slot in list(self._slots.items()):
            self._cancelled.add(job_id)
            self.pool.cancel(slot)
        tasks = list(self._tasks.values())
        if tasks:
            await asyncio.wait(tasks, timeout=5.0)


__all__ = ["CancelToken", "JobFn", "JobRunner", "Progress"]
