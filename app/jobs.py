"""Long jobs (friction-ID, fits) off the event loop: a worker thread each, progress and cancel.

A job's state lives in the database (queued → running → done | failed | cancelled), so any
client can poll it. The job function gets ``progress(fraction, message)`` and a cancel token
that works both as a callable (``cancel() -> bool``) and as an event (``cancel.is_set()``).
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from app.db import Database
from app.errors import NotFound, TooManyRequests
from tracker.errors import JobCancelled, TrackerError

log = logging.getLogger("app.jobs")

JobFn = Callable[["Progress", "CancelToken"], dict[str, Any]]


class CancelToken(threading.Event):
    """Set to ask a job to stop; call it (or ``is_set()``) to ask whether to stop."""

    def __call__(self) -> bool:
        return self.is_set()


class Progress:
    """Writes a job's progress to the database at most every ``min_interval_s``."""

    def __init__(self, db: Database, job_id: int, min_interval_s: float = 0.1) -> None:
        self._db, self._id, self._min = db, job_id, min_interval_s
        self._last = 0.0
        self.fraction = 0.0

    def __call__(self, fraction: float, message: str = "") -> None:
        self.fraction = min(1.0, max(0.0, float(fraction)))
        now = time.monotonic()
        if now - self._last >= self._min or self.fraction >= 1.0:
            self._last = now
            self._db.update_job(self._id, progress=self.fraction, message=str(message)[:200])


class JobRunner:
    """Starts jobs in worker threads and keeps their cancel tokens."""

    def __init__(self, db: Database, max_running: int = 2) -> None:
        self.db = db
        self.max_running = max_running
        self._tokens: dict[int, CancelToken] = {}
        self._tasks: dict[int, asyncio.Task[None]] = {}

    def start(self, kind: str, params: dict[str, Any], fn: JobFn) -> int:
        """Record the job and start it; returns its id. TooManyRequests (429) when
        ``max_running`` jobs are already running."""
        if len(self._tasks) >= self.max_running:
            raise TooManyRequests(
                f"{len(self._tasks)} jobs are running (cap {self.max_running}, setting max_running_jobs); "
                "wait for one to finish or cancel it",
                retry_after_s=5.0,
            )
        job_id = self.db.add_job(kind, params)
        token = CancelToken()
        self._tokens[job_id] = token
        self._tasks[job_id] = asyncio.create_task(self._run(job_id, fn, token), name=f"job-{job_id}")
        return job_id

    async def _run(self, job_id: int, fn: JobFn, token: CancelToken) -> None:
        self.db.update_job(job_id, state="running")
        progress = Progress(self.db, job_id)
        try:
            result = await asyncio.to_thread(fn, progress, token)
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
            if token.is_set():
                self.db.update_job(job_id, state="cancelled", message="cancelled")
            else:
                self.db.update_job(job_id, state="done", progress=1.0, message="done", result=result)
        finally:
            self._tokens.pop(job_id, None)
            self._tasks.pop(job_id, None)

    def cancel(self, job_id: int) -> dict[str, Any]:
        """Ask a job to stop; NotFound when unknown. Returns its record."""
        job = self.db.get_job(job_id)
        if job is None:
            raise NotFound(f"no job {job_id}")
        token = self._tokens.get(job_id)
        if token is not None:
            token.set()
            self.db.update_job(job_id, message="cancelling")
        return self.db.get_job(job_id) or job

    async def wait(self, job_id: int) -> None:
        task = self._tasks.get(job_id)
        if task is not None:
            await asyncio.shield(task)

    async def shutdown(self) -> None:
        for token in self._tokens.values():
            token.set()
        tasks = list(self._tasks.values())
        if tasks:
            await asyncio.wait(tasks, timeout=5.0)
