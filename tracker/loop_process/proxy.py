"""The engine in a process of its own, seen from the service through the engine's own surface.

:class:`LoopProcess` spawns :func:`tracker.loop_process.child.serve` (``multiprocessing``'s
"spawn": the service has threads that must not be forked), which builds the engine and its
driver with ``build(arg)`` and runs the loop there. Calls that change the engine (point, jog,
tracking, gains, models, recording, faults) go over a pipe and are answered between chunks;
errors come back as the same exception types. Status, loop timing and telemetry are read from
shared memory without waiting for the loop. What takes python-control tenths of a second (a
gain set's margins, a controller design on a new model, a model's check against the recent
motion) is computed here, off the loop, and handed over with the call (``Engine.set_gains``'
``report``, ``Engine.set_model``'s ``check`` and ``design``).

:meth:`LoopProcess.run` starts the loop and, until it ends, every ``poll_s`` forwards new
snapshots to the subscribers and pushes the target source's target (the talker tracker lives in
the service) into shared memory. If the process dies the proxy latches a fault (status, health
and every moving call say so) and the service keeps serving; if the service dies, the process
sees its pipe close, stops the axes and exits.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import math
import multiprocessing as mp
import threading
import time
from collections.abc import Callable
from typing import Any

from tracker.control.design import ControllerDesign, DesignReport, check_gains, design_controller
from tracker.control.gains import ControllerGains
from tracker.control.limits import SoftLimits
from tracker.engine import Engine
from tracker.errors import ConfigError, DriverFault, TrackerError
from tracker.loop_process.child import serve
from tracker.loop_process.shared import SharedLoop
from tracker.loop_process.wire import Call, Ready, Reply
from tracker.model_check import ModelCheck, check_model
from tracker.plant.model import AxisModel
from tracker.realtime import LoopTiming
from tracker.targets import TargetSource, as_target
from tracker.telemetry import EngineStatus, TelemetrySnapshot, TelemetrySubscription
from tracker.workbench.measurements.data import Measurement

CALL_TIMEOUT_S = 5.0
STALL_S = 1.0  # a running loop without a tick for this long answers no call: refused at once
POLL_S = 0.005


class LoopDriverView:
    """What the service sees of the driver in the loop's process: its faults (and the process's
    own death), enable/clear over the pipe, its description."""

    def __init__(self, proxy: LoopProcess, description: dict[str, Any], sample_period_s: float) -> None:
        self._proxy = proxy
        self._description = description
        self.sample_period_s = sample_period_s

    @property
    def enabled(self) -> bool:
        return self._proxy.driver_enabled()

    def faults(self) -> tuple[str, ...]:
        return self._proxy.faults()

    def clear_faults(self) -> None:
        self._proxy.call("clear_faults")

    def enable(self) -> None:
        self._proxy.call("enable")

    def disable(self) -> None:
        self._proxy.call("disable")

    def latch_fault(self, message: str) -> None:
        """Latch a fault in the driver (an emergency stop): the axes are disabled."""
        self._proxy.call("latch_fault", str(message))

    def describe(self) -> dict[str, Any]:
        return {**self._description, "loop_process": self._proxy.describe_process()}

    async def close(self) -> None:
        await self._proxy.close()


class LoopProcess:
    """The engine's control surface (``tracker.engine.Engine``'s) over a process boundary."""

    def __init__(self, build: Callable[[Any], Engine], arg: Any, *,  # noqa: ANN401 - build's argument
                 start_timeout_s: float = 120.0, poll_s: float = POLL_S) -> None:
        self._shared = SharedLoop.create()
        ctx = mp.get_context("spawn")
        self._conn, child_conn = ctx.Pipe()
        self._proc = ctx.Process(target=serve, args=(child_conn, build, arg, self._shared.name),
                                 name="engine-loop", daemon=True)
        self._proc.start()
        child_conn.close()
        self.pid = int(self._proc.pid or 0)
        self._lock = threading.Lock()
        self._next_id = 0
        self._poll_s = poll_s
        self._subs: set[TelemetrySubscription] = set()
        self._source: TargetSource | None = None
        self._source_name: str | None = None
        self._target_withdrawn = False
        self._last_snap: TelemetrySnapshot | None = None
        self._dead: str | None = None
        self._stop = False
        self._running = False
        self._ran = False
        self._closed = False
        self._models: dict[str, AxisModel] = {}
        self._gains: dict[str, ControllerGains] = {}
        ready = self._wait_ready(start_timeout_s)
        self.config = ready.config
        self.chunk_period_s = ready.chunk_period_s
        self.driver = LoopDriverView(self, dict(ready.driver), ready.sample_period_s)

    def _wait_ready(self, timeout_s: float) -> Ready:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if self._conn.poll(0.05):
                try:
                    msg = self._conn.recv()
                except (EOFError, OSError):
                    break
                if isinstance(msg, Reply) and msg.error is not None:
                    self._abandon()
                    raise msg.error.rebuild()
                if isinstance(msg, Ready):
                    return msg
            if not self._proc.is_alive():
                break
        code = self._proc.exitcode
        self._abandon()
        raise ConfigError(f"the control loop's process did not start (exit code {code}, "
                          f"{timeout_s:g} s allowed)")

    def _abandon(self) -> None:
        if self._proc.is_alive():
            self._proc.kill()
        self._proc.join(5.0)
        self._shared.close()
        self._shared.unlink()
        self._closed = True

    # -- calls over the pipe -------------------------------------------------------------------
    def call(self, method: str, *args: Any, timeout_s: float = CALL_TIMEOUT_S, **kwargs: Any) -> Any:  # noqa: ANN401
        """Run ``method`` of the loop's command table between two chunks and return its value
        (or raise its error). DriverFault when the process is gone or does not answer, and at
        once when its loop is stalled (a call would hold the caller, the web's event loop, for
        ``timeout_s``)."""
        with self._lock:
            if self._dead is not None:
                raise DriverFault(self._dead)
            if self._running and method != "stop":
                age_s = self._shared.read_timing(time.perf_counter()).last_tick_age_s
                if math.isfinite(age_s) and age_s > STALL_S:
                    raise DriverFault(f"the control loop is stalled (no tick for {age_s:.1f} s): "
                                      f"{method} refused")
            self._next_id += 1
            call_id = self._next_id
            try:
                self._conn.send(Call(call_id, method, args, kwargs))
                end = time.monotonic() + timeout_s
                while True:
                    if not self._conn.poll(max(0.0, end - time.monotonic())):
                        raise DriverFault(f"the control loop's process did not answer {method} "
                                          f"within {timeout_s:g} s")
                    reply = self._conn.recv()
                    if isinstance(reply, Reply) and reply.call_id == call_id:
                        break  # an older reply (its caller timed out) is dropped
            except (EOFError, OSError, BrokenPipeError):
                self._latch_death()
                raise DriverFault(self._dead or "the control loop's process is gone") from None
        if reply.error is not None:
            raise reply.error.rebuild()
        return reply.value

    def _latch_death(self) -> None:
        if self._dead is None:
            self._proc.join(0.5)
            code = self._proc.exitcode
            how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
            self._dead = (f"the control loop's process ({self.pid}) ended ({how}): the axes are "
                          "stopped; restart the service")

    # -- the control surface (Engine's) ----------------------------------------------------------
    def stop(self) -> None:
        """Ask ``run`` to stop the loop and return."""
        self._stop = True

    def subscribe(self, maxsize: int = 256) -> TelemetrySubscription:
        sub = TelemetrySubscription(maxsize, self._subs.discard)
        self._subs.add(sub)
        return sub

    def require_no_fault(self) -> None:
        faults = self.faults()
        if faults:
            raise DriverFault(
                f"drive fault latched ({'; '.join(faults)}): pointing, jogging and tracking are "
                "refused until the fault is cleared")

    def set_tracking(self, enabled: bool) -> None:
        self.call("set_tracking", bool(enabled))

    def set_target_source(self, source: TargetSource | None) -> None:
        name = None if source is None else str(getattr(source, "name", type(source).__name__))
        self._source, self._source_name = source, name
        self._shared.write_target(None)
        self.call("set_target_source", name)

    def point(self, pan_rad: float, tilt_rad: float) -> None:
        self.call("point", float(pan_rad), float(tilt_rad))

    def release(self) -> None:
        self.call("release")

    def jog(self, axis: str, rate_rad_s: float, timeout_s: float = 0.5) -> None:
        self.call("jog", axis, float(rate_rad_s), float(timeout_s))  # positional: not call's timeout

    def gains(self, axis: str) -> ControllerGains:
        if axis not in self._gains:
            self._gains[axis] = self.call("gains", axis)
        return self._gains[axis]

    def model(self, axis: str) -> AxisModel:
        if axis not in self._models:
            self._models[axis] = self.call("model", axis)
        return self._models[axis]

    def limits(self, axis: str) -> SoftLimits:
        out: SoftLimits = self.call("limits", axis)
        return out

    def set_gains(self, axis: str, gains: ControllerGains) -> DesignReport:
        """Margins checked here (off the loop), the gains packed and used in the loop's process."""
        report = check_gains(self.model(axis), gains, self.config.min_phase_margin_deg)
        if not report.ok:
            raise ConfigError(f"{axis} gains refused: {report.describe()}")
        out: DesignReport = self.call("set_gains", axis, gains, report)
        self._gains[axis] = gains
        return out

    def recent_motion(self, axis: str) -> Measurement | None:
        out: Measurement | None = self.call("recent_motion", axis)
        return out

    def check_model(self, axis: str, model: AxisModel) -> ModelCheck:
        return check_model(axis, self.recent_motion(axis), model, self.model(axis))

    def set_model(self, axis: str, model: AxisModel, check: ModelCheck | None = None,
                  design: ControllerDesign | None = None, **options: Any) -> ControllerDesign:
        """Designed and checked here (off the loop), packed against the soft limits and used in
        the loop's process (``Engine.set_model``)."""
        current = self.model(axis)  # an unknown axis is refused here, by the loop's process
        if design is None:
            design = design_controller(model, self.config.controller, axis=axis, **options)
        if design.report.ok and design.report.phase_margin_deg >= self.config.min_phase_margin_deg:
            check = check_model(axis, self.recent_motion(axis), model, current) if check is None else check
        out: ControllerDesign = self.call("set_model", axis, model, check=check, design=design)
        self._models[axis], self._gains[axis] = model, out.gains
        return out

    def start_recording(self) -> None:
        self.call("start_recording")

    def stop_recording(self) -> dict[str, Measurement]:
        out: dict[str, Measurement] = self.call("stop_recording")
        return out

    def observed(self, axis: str) -> tuple[float, float]:
        out: tuple[float, float] = self.call("observed", axis)
        return out

    # -- read from shared memory -----------------------------------------------------------------
    def status(self) -> EngineStatus:
        read = None if self._closed else self._shared.read_status()
        if read is None:
            st = EngineStatus(0.0, 0.0, 0.0, 0.0, 0.0, "hold", False, (), None)
        else:
            st = read[0]
        if self._dead is not None:
            return EngineStatus(st.t_s, st.pan_rad, st.tilt_rad, st.pan_target_rad, st.tilt_target_rad,
                                "fault", st.tracking, (*st.faults, self._dead), st.active_talker)
        return st

    def faults(self) -> tuple[str, ...]:
        return self.status().faults

    def driver_enabled(self) -> bool:
        read = None if self._closed or self._dead else self._shared.read_status()
        return bool(read is not None and read[1])

    @property
    def mode(self) -> str:
        return self.status().mode

    def timing(self) -> LoopTiming:
        if self._closed:
            return LoopTiming(self.chunk_period_s, 0, 0.0, 0.0, 0.0, 0, 0, False, False)
        t = self._shared.read_timing(time.perf_counter())
        if self._dead is not None or not self._proc.is_alive():
            return dataclasses.replace(t, running=False)
        return t

    def describe_process(self) -> dict[str, Any]:
        state = "running" if self._dead is None and self._proc.is_alive() else "ended"
        return {"pid": self.pid, "state": state, "fault": self._dead}

    @property
    def alive(self) -> bool:
        return self._dead is None and self._proc.is_alive()

    # -- the loop --------------------------------------------------------------------------------
    async def run(self, realtime: bool = True, duration_s: float | None = None) -> None:
        """Start the loop in its process; until it ends, forward telemetry and push targets."""
        if self._running or self._ran:
            raise ConfigError("the loop's process runs once: it is running or has ended")
        self._running = self._ran = True
        cursor = self._shared.ring_head()
        try:
            self.call("run", realtime=realtime, duration_s=duration_s)
            while self._proc.is_alive():
                cursor = self._forward(cursor)
                self._push_target()
                if self._stop:
                    await self._stop_process()
                    break
                await asyncio.sleep(self._poll_s)
            self._forward(cursor)
            if self._proc.exitcode not in (0, None) or (not self._stop and duration_s is None):
                self._latch_death()
                self._publish_death()
        finally:
            self._running = False
            for sub in list(self._subs):
                sub.put(None)

    def _forward(self, cursor: int) -> int:
        snaps, cursor = self._shared.read_snapshots(cursor)
        for snap in snaps:
            for sub in list(self._subs):
                sub.put(snap)
        if snaps:
            self._last_snap = snaps[-1]
        return cursor

    def _publish_death(self) -> None:
        """A last snapshot, a chunk after the last one, that says what status says: the axes
        stopped (0 V, where they were) in mode fault; telemetry would otherwise end on a frame
        of a healthy rig."""
        last = self._last_snap
        if last is None:
            return
        snap = dataclasses.replace(last, t_s=last.t_s + self.chunk_period_s, pan_u_v=0.0,
                                   tilt_u_v=0.0, mode="fault")
        for sub in list(self._subs):
            sub.put(snap)

    def _push_target(self) -> None:
        source = self._source
        if source is None:
            return
        read = self._shared.read_status()
        if read is not None and not read[0].tracking:
            # Not asked while tracking is off, as the engine in a thread does not ask it; the
            # last target is withdrawn so that tracking turned on again never starts from it.
            if not self._target_withdrawn:
                self._shared.write_target(None)
                self._target_withdrawn = True
            return
        self._target_withdrawn = False
        t_s = (read[0].t_s if read is not None else 0.0) + self.chunk_period_s
        try:
            heard = as_target(source.target_at(t_s), self._source_name or "source")
        except TrackerError:
            heard = None
        self._shared.write_target(heard)

    async def _stop_process(self, timeout_s: float = 3.0) -> None:
        with contextlib.suppress(DriverFault):
            self.call("stop", timeout_s=timeout_s)
        await asyncio.to_thread(self._proc.join, timeout_s)
        if self._proc.is_alive():
            self._proc.terminate()
            await asyncio.to_thread(self._proc.join, timeout_s)

    async def close(self) -> None:
        """Stop the process if it still runs and free the shared memory (the service's stop)."""
        if self._closed:
            return
        if self._proc.is_alive():
            await self._stop_process()
        if self._proc.is_alive():
            self._proc.kill()
            await asyncio.to_thread(self._proc.join, 5.0)
        self._closed = True
        self._conn.close()
        self._shared.close()
        self._shared.unlink()
