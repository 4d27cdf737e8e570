"""The running service: settings, database, engine, telemetry hub, control lock, worker processes
and jobs, 3D view, the stored console settings, the audit log and the metrics.

One :class:`Service` lives in ``app.state.svc`` for the lifetime of the FastAPI app; the lifespan
in :mod:`app.main` starts and stops it. Routes reach it through :func:`get_service`.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import logging
import math
import time
from typing import Annotated, Any

from fastapi import Depends, Request

from app import heavy, rig
from app.audit import AuditLog
from app.auth import ensure_admin_key
from app.backoff import BadKeyBackoff
from app.console_state import ConsoleState
from app.control_lock import ControlLock
from app.db import Database
from app.jobs import JobRunner
from app.metrics import Metrics
from app.persist import SettingsStore
from app.policy import PolicyHolder
from app.settings import Settings
from app.telemetry import TelemetryHub
from app.view_proxy import ViewSessions
from app.work import WorkPool
from app.workers import WorkerPool

log = logging.getLogger("app")


class Service:
    """Everything a request may need, created once per app."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.db = Database(settings.db_path)
        self.first_admin_key = ensure_admin_key(self.db, settings.admin_key_path)
        self.db.fail_unfinished_jobs()
        self.store = SettingsStore(self.db)
        self.console = ConsoleState(self.store)
        self.audit = AuditLog(self.db, max_rows=settings.audit_max_rows)
        self.metrics = Metrics()
        self.lock = ControlLock(ttl_s=settings.control_lock_ttl_s)
        self.hub = TelemetryHub(rate_hz=settings.telemetry_rate_hz)
        self.pool = WorkerPool(settings.job_workers, on_progress=self._job_progress, effects=settings.effects)
        self.jobs = JobRunner(self.db, self.pool, max_running=settings.max_running_jobs,
                              observe=self.metrics.job_finished)
        self.work = WorkPool(
            settings.heavy_workers, settings.heavy_queue, settings.heavy_per_key, settings.effects,
            observe=self.metrics.work_finished,
        )
        self.bad_keys = BadKeyBackoff(
            settings.bad_key_limit, settings.bad_key_window_s, settings.bad_key_max_block_s
        )
        self.policy = PolicyHolder(settings.camera_policy, self.db)
        self.engine: Any = None
        self.audio: Any = None
        self.viewer: Any = None
        self.view_sessions = ViewSessions()
        self.audio_note: str | None = None
        self._engine_task: asyncio.Task[None] | None = None
        self.engine_started_s = math.nan  # time.perf_counter() when the engine's loop was started
        self.threads_priority = 0  # the SCHED_FIFO priority the service's threads got (0: none)
        self._threads_task: asyncio.Task[None] | None = None
        self.metrics.watch(self)

    def _job_progress(self, job_id: int, fraction: float, message: str) -> None:
        self.jobs.progress(job_id, fraction, message)

    async def start(self) -> None:
        """Build and start the engine, the telemetry hub, the audio target source and the 3D view."""
        s = self.settings
        self.engine = rig.build_engine(s)
        self.console.restore(self.engine)  # before the first tick (app/console_state.py)
        self.work.warm(heavy.warm_up)
        # Everything loaded so far (numba, scipy, python-control: some 200 000 objects) out of
        # the collector's sight: a full collection over them held the GIL, and so the control
        # loop's thread, for up to a second.
        gc.collect()
        gc.freeze()
        if s.service_threads_priority > 0:
            self._threads_task = asyncio.create_task(self._keep_threads_priority(), name="priority")
        self._engine_task = asyncio.create_task(self._run_engine(), name="engine")
        self.engine_started_s = time.perf_counter()
        self.hub.start(self.engine)
        if s.audio_enabled:
            self.audio, self.audio_note = rig.attach_audio(self.engine, s, self.policy.policy)
            if self.audio is not None:
                self.policy.listeners.append(self.audio.set_policy)
            if s.track_on_start and self.audio is not None and not self.console.tracking_restored:
                self.engine.set_tracking(True)  # a newcomer first sees the camera follow the talker
        if s.viewer_enabled:
            from app.viewer import RigViewer, array_is_head_mounted, load_mics

            try:
                self.viewer = RigViewer(s.viewer_host, s.viewer_port, load_mics(s.array_file),
                                        array_is_head_mounted(s.array_file))
                self.viewer.start(self.hub, s.viewer_rate_hz)
                if self.audio is not None and hasattr(self.audio, "talkers_state"):
                    self.viewer.talkers = self.audio.talkers_state
            except OSError as exc:
                log.error("3D view not started (%s:%d): %s", s.viewer_host, s.viewer_port, exc)
                self.viewer = None

    async def _keep_threads_priority(self, every_s: float = 1.0) -> None:
        """service_threads_priority: the service's threads in SCHED_FIFO, below the loop's, so
        one holding the interpreter lock is not preempted by other processes (docs/console.md).
        A thread started later begins in the normal class (SCHED_RESET_ON_FORK, which keeps the
        worker processes there too): swept in every ``every_s``."""
        from tracker.realtime import raise_process_threads

        priority = self.settings.service_threads_priority
        while self.engine.timing().ticks == 0:  # the loop's thread first takes its own priority
            await asyncio.sleep(0.05)
        while True:
            _, refusal = raise_process_threads(priority)  # ~0.1 ms
            if refusal is not None:
                log.warning("service_threads_priority %d refused (%s): normal scheduling", priority, refusal)
                return
            self.threads_priority = priority
            await asyncio.sleep(every_s)

    async def _run_engine(self) -> None:
        try:
            await self.engine.run(realtime=self.settings.realtime)
        except asyncio.CancelledError:
            raise
        except Exception:
            log.exception("the engine loop stopped with an error")

    def revoke_key(self, key_id: int) -> None:
        """Revoke a key everywhere at once: stored, its WebSockets closed, its manual control freed."""
        self.db.revoke_key(key_id)
        self.hub.disconnect_key(key_id, "API key revoked")
        self.view_sessions.end_key(key_id)
        self.lock.release_key(key_id)

    async def stop(self) -> None:
        if self._threads_task is not None:
            self._threads_task.cancel()
        self.work.close()
        await self.jobs.shutdown()
        await asyncio.to_thread(self.pool.shutdown)
        if self.viewer is not None:
            await self.viewer.stop()
        if self.audio is not None:
            with contextlib.suppress(Exception):
                await rig.detach_audio(self.audio)
        if self.engine is not None:
            self.engine.stop()
        if self._engine_task is not None:
            try:
                await asyncio.wait_for(self._engine_task, timeout=3.0)
            except (TimeoutError, asyncio.CancelledError):
                self._engine_task.cancel()
        if self.engine is not None:
            with contextlib.suppress(Exception):
                await rig.close_driver(self.engine)
        await self.hub.stop()
        self.db.close()

    @property
    def engine_running(self) -> bool:
        return self._engine_task is not None and not self._engine_task.done()

    def limits_deg(self) -> dict[str, float]:
        """Soft limits per axis (± degrees)."""
        return {axis: math.degrees(rig.soft_limit_rad(self.engine, axis)) for axis in ("pan", "tilt")}


def get_service(request: Request) -> Service:
    svc: Service = request.app.state.svc
    return svc


Svc = Annotated[Service, Depends(get_service)]
