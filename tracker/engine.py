"""The engine loop: target source → shaped, guarded controllers of both axes → driver → telemetry.

Both axes run at 1 kHz of simulated (or driver) time in chunks of ``EngineConfig.chunk_s``
(10 ms): on the twin the whole chunk runs compiled (controller + plant); on another driver
the compiled controller runs sample by sample through the driver (a serial rig waits for each
sample's due time in its ``tick``). After each chunk the engine publishes one
:class:`TelemetrySnapshot` (100 Hz). ``run(realtime=True)`` runs the chunks in the engine's own
thread, paced to the wall clock by deadlines (:class:`tracker.realtime.PacedLoop`), so nothing on
the event loop (requests, uploads, WebSocket viewers) can delay a tick; :meth:`Engine.timing`
says how late the ticks were. ``realtime=False`` runs as fast as possible on the event loop
(batch, tests).

Threads: the control surface (``point``, ``jog``, ``set_gains``, ``status`` ...) may be called
from any thread; a lock keeps each call and the engine's bookkeeping around a chunk apart (not
the chunk's run through the driver, and not the controller design, which happens first).
Subscriptions are thread-safe (:class:`tracker.telemetry.TelemetrySubscription`).

A PTZ camera (:class:`tracker.drivers.camera.CameraDriver`) closes its own loop: the engine
then sends it each chunk's last target instead of volts and reads back where it points (the
controllers are not used; the telemetry's command is 0 V). ``run`` starts a driver that has a
link (``start()``: a camera, a serial rig); ``enable_on_start`` waits until it is ``ready`` and
holds where it is.

Modes: "manual" (``point``/``jog`` hold until ``release`` or ``set_tracking(True)``),
"tracking" (targets from the source), "hold" (no target: keep the last one), "disabled"
(driver disabled), "fault" (a latched driver fault; the driver disables itself, the manual
override ends, and ``point``, ``jog`` and ``set_tracking(True)`` raise DriverFault until the
driver's faults are cleared). Targets from the source are queried once per chunk and
interpolated across it (10 ms latency).

The soft-limit guard counts on each axis's rated braking (``EngineConfig.envelopes``), not on
the controller's model; a model offered with :meth:`Engine.set_model` must first predict the
axis's last ``RECENT_S`` seconds (:mod:`tracker.model_check`).
"""

from __future__ import annotations

import asyncio
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.control.closed_loop import N_REC, R_U, R_Y
from tracker.control.design import (
    DEFAULT_CONTROLLER,
    ControllerDesign,
    DesignReport,
    check_gains,
    design_controller,
)
from tracker.control.envelope import BrakingEnvelope
from tracker.control.gains import ControllerGains
from tracker.control.limits import GUARD_MARGIN_RAD, SoftLimits
from tracker.control.loop import S_INIT, S_OM, S_REF, S_TH, controller_step, new_state, pack_controller
from tracker.control.trajectory import DEFAULT_LIMITS, TrajectoryLimits
from tracker.drivers.camera import CameraDriver
from tracker.drivers.motor import AXES, ClosedLoopDriver, MotorDriver
from tracker.errors import ConfigError, DriverFault, ModelRefused
from tracker.model_check import RECENT_S, ModelCheck, check_model
from tracker.plant.model import AxisModel
from tracker.realtime import LoopTiming, PacedLoop
from tracker.recording import RecentLog, Recorder
from tracker.targets import TargetSource, as_target
from tracker.telemetry import EngineStatus, TelemetrySnapshot, TelemetrySubscription
from tracker.workbench.measurements.data import Measurement

MODES = ("tracking", "manual", "hold", "disabled", "fault")
# The real-time loop's first second of ticks is its warm-up (the first chunk compiles or loads
# the numba kernels): its lateness is reported apart (tracker.realtime.TickStats).
WARM_UP_S = 1.0


_MOTOR_MEMBERS = tuple(m for m in MotorDriver.__dict__ if not m.startswith("_"))


@dataclass(frozen=True, slots=True)
class EngineConfig:
    """Engine settings. ``models`` are the design models (default: the seed presets)."""

    controller: str = DEFAULT_CONTROLLER
    min_phase_margin_deg: float = 45.0
    chunk_s: float = 0.01
    shaping: dict[str, TrajectoryLimits] = field(default_factory=lambda: dict(DEFAULT_LIMITS))
    models: dict[str, AxisModel] | None = None
    enable_on_start: bool = True  # enable the driver when run() starts the first time
    # The site's mount margin: the soft-limit guard's line sits this far inside the limits
    # (tracker.control.limits: a belt the model does not know needs its twist at full torque).
    guard_margin_rad: float = GUARD_MARGIN_RAD
    # The rated braking of each axis the soft-limit guard counts on, whatever the model says
    # (default: the seed hardware's, BrakingEnvelope.for_axis; a heavier payload lowers it).
    envelopes: dict[str, BrakingEnvelope] | None = None
    # SCHED_FIFO priority of the real-time loop's thread (0: the normal class; tracker.realtime).
    loop_priority: int = 0

    def __post_init__(self) -> None:
        for a in AXES:  # a bad margin is refused here, naming itself, not at the first chunk
            SoftLimits.for_axis(a, self.guard_margin_rad)


class _Axis:
    """Controller state of one axis."""

    def __init__(
        self,
        name: str,
        model: AxisModel,
        gains: ControllerGains,
        shaping: TrajectoryLimits,
        dt: float,
        guard_margin_rad: float = GUARD_MARGIN_RAD,
        envelope: BrakingEnvelope | None = None,
    ) -> None:
        self.name = name
        self.model = model
        self.limits = SoftLimits.for_axis(name, guard_margin_rad)
        self.envelope = envelope if envelope is not None else BrakingEnvelope.for_axis(name)
        self.shaping = shaping
        self.dt = dt
        self.gains = gains
        self.cp = self.pack(model, gains)
        self.cs = new_state()
        self.target_rad = 0.0
        self.u_v = 0.0
        self.y_rad = 0.0

    def pack(self, model: AxisModel, gains: ControllerGains) -> NDArray[np.float64]:
        """The packed controller for ``model`` and ``gains`` (the guard counting on the axis's
        rated braking, ``self.envelope``; ConfigError when packing refuses them, e.g. a belt too
        soft for the limits); nothing changes yet."""
        return pack_controller(model, gains, self.dt, self.limits, self.shaping, envelope=self.envelope)

    def use(self, model: AxisModel, gains: ControllerGains, cp: NDArray[np.float64]) -> None:
        """Switch to a controller made by :meth:`pack` (the engine's lock held)."""
        self.model, self.gains, self.cp = model, gains, cp


class Engine:
    """The tracking engine on a motor driver (see the module docstring)."""

    def __init__(self, driver: MotorDriver | CameraDriver, config: EngineConfig | None = None) -> None:
        self._driver = driver
        # The compiled fast path, if the driver has one (decided once: Protocol checks are slow).
        self._fast: ClosedLoopDriver | None = driver if isinstance(driver, ClosedLoopDriver) else None
        self._camera: CameraDriver | None = driver if isinstance(driver, CameraDriver) else None
        self._motor: MotorDriver | None = (
            driver if self._camera is None and isinstance(driver, MotorDriver) else None)
        if self._camera is None and self._motor is None and self._fast is None:
            missing = [m for m in _MOTOR_MEMBERS if not hasattr(driver, m)]
            raise ConfigError(f"driver {type(driver).__name__} is neither a MotorDriver nor a "
                              f"CameraDriver (it lacks {', '.join(missing) or 'a member'}: "
                              "tracker/drivers/motor.py)")
        self._enable_when_ready = False  # a camera: enable_on_start waits for its first position
        self.config = config or EngineConfig()
        self._dt = driver.sample_period_s
        self._n_chunk = max(1, int(round(self.config.chunk_s / self._dt)))
        models = self.config.models or {a: AxisModel.for_axis(a) for a in AXES}
        envelopes = self.config.envelopes or {}
        self._axes: dict[str, _Axis] = {}
        for a in AXES:
            design = design_controller(models[a], self.config.controller, axis=a)
            self._axes[a] = _Axis(
                a,
                models[a],
                design.gains,
                self.config.shaping[a],
                self._dt,
                self.config.guard_margin_rad,
                envelopes.get(a),
            )
        self._recent = RecentLog(AXES, int(round(RECENT_S / self._dt)))
        self._t = 0.0
        self._k = 0  # samples run; time is k·dt (no drift)
        self._tracking = False
        self._manual = False
        self._source: TargetSource | None = None
        self._last_target: dict[str, float] = {a: 0.0 for a in AXES}
        self._estimate: tuple[float | None, float | None] = (None, None)
        self._talker: str | None = None
        self._source_name: str | None = None
        self._jog: dict[str, tuple[float, float]] = {}  # axis -> (rate, deadline t_s)
        self._subscribers: set[TelemetrySubscription] = set()
        self._recorder: Recorder | None = None
        self._stop = False
        self._running = False
        self._initialised = False
        self._talker_fresh = False  # the source gave a target in the latest chunk
        self._ran = False  # enable_on_start applies to the first run only
        self._lock = threading.RLock()
        self._paced: PacedLoop | None = None

    # -- control surface --------------------------------------------------------------------
    @property
    def driver(self) -> MotorDriver | CameraDriver:
        """The motor driver (or PTZ camera) the engine commands."""
        return self._driver

    def stop(self) -> None:
        """Ask ``run`` to return after the current chunk."""
        self._stop = True

    def subscribe(self, maxsize: int = 256) -> TelemetrySubscription:
        """A new telemetry subscription (drop-oldest queue of ``maxsize``)."""
        sub = TelemetrySubscription(maxsize, self._subscribers.discard)
        self._subscribers.add(sub)
        return sub

    def require_no_fault(self) -> None:
        """Raise DriverFault naming the latched faults, if any (commands that move the axes are
        refused until the driver's faults are cleared)."""
        faults = self._driver.faults()
        if faults:
            raise DriverFault(
                f"drive fault latched ({'; '.join(faults)}): pointing, jogging and tracking are "
                "refused until the fault is cleared"
            )

    def set_tracking(self, enabled: bool) -> None:
        """Follow the target source (True; ends a manual override) or hold (False).

        Raises DriverFault when turning tracking on while a drive fault is latched."""
        with self._lock:
            if enabled:
                self.require_no_fault()
            self._tracking = bool(enabled)
            if enabled:
                self._manual = False
                self._jog.clear()

    def set_target_source(self, source: TargetSource | None) -> None:
        """Plug in (or remove) the source of targets for tracking mode."""
        name = None if source is None else str(getattr(source, "name", type(source).__name__))
        with self._lock:
            self._source, self._source_name = source, name

    def point(self, pan_rad: float, tilt_rad: float) -> None:
        """Manual override: point at (pan, tilt) until ``release`` or ``set_tracking(True)``.

        Raises ConfigError outside the soft limits, DriverFault while a drive fault is latched."""
        self.require_no_fault()
        for axis, value in (("pan", pan_rad), ("tilt", tilt_rad)):
            self._axes[axis].limits.check_target(axis, float(value))
        with self._lock:
            self._manual = True
            self._jog.clear()
            self._last_target["pan"] = float(pan_rad)
            self._last_target["tilt"] = float(tilt_rad)

    def release(self) -> None:
        """End a manual override (back to tracking if enabled, else hold)."""
        with self._lock:
            self._manual = False
            self._jog.clear()

    def jog(self, axis: str, rate_rad_s: float, timeout_s: float = 0.5) -> None:
        """Move ``axis`` at ``rate_rad_s`` until a rate of 0, or ``timeout_s`` without renewal.

        A rate other than 0 raises DriverFault while a drive fault is latched (stopping is
        always allowed)."""
        ax = self._axis(axis)
        if rate_rad_s != 0.0:
            self.require_no_fault()
        if not (math.isfinite(rate_rad_s) and math.isfinite(timeout_s) and timeout_s > 0):
            raise ConfigError(
                f"jog {axis}: rate {rate_rad_s!r} rad/s and timeout {timeout_s!r} s must be finite"
            )
        limit = ax.shaping.rate_rad_s
        if abs(rate_rad_s) > limit:
            raise ConfigError(
                f"jog {axis}: rate {rate_rad_s:g} rad/s exceeds the axis rate limit {limit:g} rad/s"
            )
        with self._lock:
            if not self._manual:
                self._manual = True
                for a in AXES:  # start from where the axes are
                    self._last_target[a] = self._axes[a].y_rad if self._initialised else self._last_target[a]
            if rate_rad_s == 0.0:
                self._jog.pop(axis, None)
            else:
                self._jog[axis] = (float(rate_rad_s), self._t + float(timeout_s))

    def gains(self, axis: str) -> ControllerGains:
        """The gains in use on ``axis``."""
        return self._axis(axis).gains

    def set_gains(
        self, axis: str, gains: ControllerGains, report: DesignReport | None = None
    ) -> DesignReport:
        """Use ``gains`` on ``axis`` if its linearised loop is stable with enough phase margin.

        ``report`` is :func:`check_gains`' result for the axis's current model, computed by the
        caller off the loop (~0.1 s of python-control; :mod:`tracker.loop_process`); computed
        here when None. Raises ConfigError carrying the computed margins otherwise.
        """
        ax = self._axis(axis)
        if report is None:
            report = check_gains(ax.model, gains, self.config.min_phase_margin_deg)
        if not report.ok:
            raise ConfigError(f"{axis} gains refused: {report.describe()}")
        cp = ax.pack(ax.model, gains)
        with self._lock:
            ax.use(ax.model, gains, cp)
        return report

    def limits(self, axis: str) -> SoftLimits:
        """The soft limits of ``axis`` and its guard's margins."""
        return self._axis(axis).limits

    def model(self, axis: str) -> AxisModel:
        """The model the controller of ``axis`` is designed on."""
        return self._axis(axis).model

    def recent_motion(self, axis: str) -> Measurement | None:
        """The last ``RECENT_S`` seconds of ``axis`` (t, u, θ; a copy), None before there are enough."""
        self._axis(axis)
        with self._lock:
            return self._recent.measurement(axis)

    def check_model(self, axis: str, model: AxisModel) -> ModelCheck:
        """Does ``model`` predict ``axis``'s recent motion (:func:`tracker.model_check.check_model`)?"""
        return check_model(axis, self.recent_motion(axis), model, self.model(axis))

    def set_model(
        self, axis: str, model: AxisModel, check: ModelCheck | None = None,
        design: ControllerDesign | None = None, **options: Any
    ) -> ControllerDesign:
        """Redesign ``axis``'s controller on ``model`` (e.g. one the workbench fitted) and use it.

        ``model`` must first predict the axis's recent motion: ``check`` is
        :meth:`check_model`'s result (computed here when None; a caller may compute it off the
        loop's thread); ModelRefused (a ConfigError with the figures) when it does not.
        ``design`` is :func:`design_controller`'s result on ``model`` (the engine's controller),
        computed by the caller off the loop (~0.2 s; :mod:`tracker.loop_process`); designed here
        when None, with ``options`` (e.g. ``crossover_hz=17.0``). The limits, shaping and
        controller name stay; refused (ConfigError with the margins) like :meth:`set_gains`
        when the new design misses the phase-margin floor, and (ConfigError) when the guard
        cannot take the model (a belt too soft for the limits). Nothing changes when refused.
        """
        ax = self._axis(axis)
        if design is None:
            design = design_controller(model, self.config.controller, axis=axis, **options)
        if not design.report.ok or design.report.phase_margin_deg < self.config.min_phase_margin_deg:
            raise ConfigError(f"{axis} redesign refused: {design.report.describe()}")
        cp = ax.pack(model, design.gains)
        check = self.check_model(axis, model) if check is None else check  # off the lock (slow)
        if check.axis != axis:
            raise ConfigError(f"set_model {axis}: the check given is for {check.axis}")
        if not check.accepted:
            raise ModelRefused(f"{axis} model refused: {check.describe()}", check.to_dict())
        with self._lock:
            ax.use(model, design.gains, cp)
        return design

    def start_recording(self) -> None:
        """Start recording t, u, theta of each axis."""
        with self._lock:
            self._recorder = Recorder(AXES)

    def stop_recording(self) -> dict[str, Measurement]:
        """Stop recording; per-axis measurements in the log format."""
        with self._lock:
            if self._recorder is None:
                raise ConfigError("stop_recording: recording was not started")
            rec, self._recorder = self._recorder, None
        return rec.measurements()

    def status(self) -> EngineStatus:
        """The engine's state now."""
        with self._lock:
            p, t = self._axes["pan"], self._axes["tilt"]
            return EngineStatus(
                self._t,
                p.y_rad,
                t.y_rad,
                p.target_rad,
                t.target_rad,
                self.mode,
                self._tracking,
                self._driver.faults(),
                self._talker,
            )

    def timing(self) -> LoopTiming:
        """How well the real-time loop keeps its clock (zeros before the first real-time run)."""
        paced = self._paced
        if paced is None:
            period = self._n_chunk * self._dt
            return LoopTiming(period, 0, 0.0, 0.0, 0.0, 0, 0, False, False)
        return paced.timing()

    @property
    def mode(self) -> str:
        """One of MODES."""
        if self._driver.faults():
            return "fault"
        if not self._driver.enabled:
            return "disabled"
        if self._manual:
            return "manual"
        if (
            self._tracking
            and self._source is not None
            and self._source_name is not None
            and self._talker_fresh
        ):
            return "tracking"
        return "hold"

    # -- the loop ---------------------------------------------------------------------------
    async def run(
        self,
        realtime: bool = True,
        duration_s: float | None = None,
        on_chunk: Callable[[TelemetrySnapshot], None] | None = None,
    ) -> None:
        """Run until ``stop()`` or ``duration_s`` of engine time have passed (``realtime``: in
        the engine's own thread, paced to the wall clock; else on the event loop, at once).
        ``on_chunk(snapshot)`` runs after each chunk in the loop's thread, before the next is due
        (a loop in its own process takes its commands there: :mod:`tracker.loop_process`)."""
        if self._running:
            raise ConfigError("engine is already running")
        self._running = True
        self._stop = False
        first_run, self._ran = not self._ran, True
        start = getattr(self._driver, "start", None)
        if callable(start):  # a link to bring up (camera, serial rig): needs the event loop here
            start()
        self._enable_when_ready = first_run and self.config.enable_on_start
        end = None if duration_s is None else self._t + float(duration_s)
        try:
            if realtime:
                await self._run_paced(end, on_chunk)
            else:
                while not self._stop and (end is None or self._t < end - 1e-12):
                    snap = self.step_chunk()
                    if on_chunk is not None:
                        on_chunk(snap)
                    await asyncio.sleep(0)
        finally:
            self._running = False
            for sub in list(self._subscribers):
                sub.put(None)

    async def _run_paced(
        self, end: float | None, on_chunk: Callable[[TelemetrySnapshot], None] | None = None
    ) -> None:
        """The chunks in a :class:`PacedLoop` thread; returns (or raises) when it ends."""
        loop = asyncio.get_running_loop()
        done: asyncio.Future[None] = loop.create_future()

        def step() -> bool:
            if self._stop or (end is not None and self._t >= end - 1e-12):
                return False
            snap = self.step_chunk()
            if on_chunk is not None:
                on_chunk(snap)
            return True

        def finish(error: BaseException | None) -> None:
            if not done.done():
                if error is None:
                    done.set_result(None)
                else:
                    done.set_exception(error)

        def on_exit(error: BaseException | None) -> None:
            try:
                loop.call_soon_threadsafe(finish, error)
            except RuntimeError:  # the event loop is gone: nobody waits
                pass

        period = self._n_chunk * self._dt
        paced = PacedLoop(period, step, on_exit=on_exit, name="engine-loop",
                          priority=self.config.loop_priority,
                          warm_up_ticks=max(2, math.ceil(WARM_UP_S / period)))
        self._paced = paced
        paced.start()
        try:
            await done
        finally:
            self._stop = True
            paced.join(2.0)

    def step_chunk(self) -> TelemetrySnapshot:
        """Run one chunk of both axes and publish its snapshot (the loop's body; sync)."""
        n = self._n_chunk
        with self._lock:
            if not self._initialised:
                for a, ax in self._axes.items():
                    ax.y_rad = self._driver.read_encoder(a)
                    if not self._manual:
                        self._last_target[a] = ax.y_rad
                    ax.target_rad = self._last_target[a]
                self._initialised = True
            if self._enable_when_ready:
                self._enable_if_ready()
            if self._driver.faults():  # a latched fault ends the manual override: hold where it stops
                self._manual = False
                self._jog.clear()
            targets = self._chunk_targets(n)
            t_chunk = self._t + np.arange(n, dtype=np.float64) * self._dt
        records: dict[str, np.ndarray] = {}  # the driver runs without the lock (a serial rig waits)
        if self._camera is not None:
            records = self._run_camera(self._camera, targets, n)
        elif self._fast is not None:
            for a, ax in self._axes.items():
                records[a] = self._fast.run_closed_loop(a, ax.cp, ax.cs, targets[a])
        else:
            records = self._run_per_sample(targets, n)
        with self._lock:
            for a, ax in self._axes.items():
                rec = records[a]
                ax.y_rad = float(rec[-1, R_Y])
                ax.u_v = float(rec[-1, R_U])
                ax.target_rad = float(targets[a][-1])
                self._recent.add(a, t_chunk, rec[:, R_U], rec[:, R_Y])
                if self._recorder is not None:
                    self._recorder.add(a, t_chunk, rec[:, R_U], rec[:, R_Y])
            self._k += n
            self._t = self._k * self._dt
            snap = self._snapshot()
        for sub in list(self._subscribers):
            sub.put(snap)
        return snap

    def _enable_if_ready(self) -> None:
        """enable_on_start: once the driver is ready (a link up and a position read), enable
        it holding where it stands; given up if a fault is latched first."""
        drv = self._driver
        if drv.faults() or drv.enabled:
            self._enable_when_ready = False
            return
        if not getattr(drv, "ready", True):
            return
        self._enable_when_ready = False
        try:
            drv.enable()
        except DriverFault:
            return
        for a, ax in self._axes.items():  # start from where it is: nothing moves until told to
            ax.y_rad = drv.read_encoder(a)
            if not self._manual:
                self._last_target[a] = ax.y_rad

    def _run_per_sample(self, targets: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
        out = {a: np.zeros((n, N_REC)) for a in self._axes}
        drv = self._motor
        assert drv is not None
        lent = getattr(drv, "held_axis", None)  # lent to a job: its commands, not the controller's
        for k in range(n):
            for a, ax in self._axes.items():
                y = drv.read_encoder(a)
                active = drv.enabled and a != lent
                u = controller_step(ax.cp, ax.cs, y, float(targets[a][k])) if active else 0.0
                if not active:
                    ax.cs[S_INIT] = 0.0  # re-initialise on re-enable or hand-back
                drv.command(a, u)
                out[a][k, R_Y], out[a][k, R_U] = y, u
                out[a][k, 3], out[a][k, 4] = ax.cs[S_REF], ax.cs[S_OM]
            drv.tick()
        return out

    def _run_camera(self, cam: CameraDriver, targets: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
        """One chunk on a PTZ camera: the chunk's last target out, the camera's angle in."""
        out = {}
        for a in AXES:
            if cam.enabled:
                cam.set_target(a, float(targets[a][-1]))
            rec = np.zeros((n, N_REC))
            rec[:, R_Y] = cam.read_encoder(a)
            out[a] = rec
        return out

    def _chunk_targets(self, n: int) -> dict[str, np.ndarray]:
        start = dict(self._last_target)
        self._talker_fresh = False
        heard = None
        if self._tracking and self._source is not None:
            # Asked even when manual or disabled: the console shows what the localizer hears.
            heard = as_target(self._source.target_at(self._t + n * self._dt), self._source_name or "source")
            if heard is not None:
                self._talker_fresh = True
                self._talker = heard.talker
                self._estimate = (heard.azimuth_rad, heard.elevation_rad)
        if not self._driver.enabled and not self._manual:
            # Disabled or faulted: hold wherever the axes are, so re-enabling does not jump.
            for a, ax in self._axes.items():
                self._last_target[a] = ax.y_rad
        elif self._manual:
            for a, (rate, deadline) in list(self._jog.items()):
                if self._t >= deadline:
                    del self._jog[a]
                    continue
                lim = self._axes[a].limits
                edge = lim.upper_rad - lim.target_margin_rad
                self._last_target[a] = float(np.clip(self._last_target[a] + rate * n * self._dt, -edge, edge))
        elif heard is not None:
            for a, value in (("pan", heard.pan_rad), ("tilt", heard.tilt_rad)):
                lim = self._axes[a].limits
                self._last_target[a] = float(np.clip(value, lim.lower_rad, lim.upper_rad))
        lent = getattr(self._driver, "held_axis", None)
        if lent is not None:  # an axis lent to a job (a sweep): held wherever the job takes it
            self._last_target[lent] = start[lent] = self._axes[lent].y_rad
        frac = np.arange(1, n + 1) / n
        return {a: start[a] + (self._last_target[a] - start[a]) * frac for a in AXES}

    def _snapshot(self) -> TelemetrySnapshot:
        p, t = self._axes["pan"], self._axes["tilt"]
        source = (
            self._source_name
            if (self._tracking and not self._manual)
            else ("manual" if self._manual else None)
        )
        return TelemetrySnapshot(
            self._t,
            p.y_rad,
            t.y_rad,
            p.target_rad,
            t.target_rad,
            p.u_v,
            t.u_v,
            self.mode,
            self._tracking,
            source,
            self._estimate[0],
            self._estimate[1],
        )

    def _axis(self, axis: str) -> _Axis:
        try:
            return self._axes[axis]
        except KeyError:
            raise ConfigError(f"unknown axis {axis!r}; axes are {', '.join(AXES)}") from None

    def observed(self, axis: str) -> tuple[float, float]:
        """The observer's angle (rad) and velocity (rad/s) of ``axis``."""
        cs = self._axis(axis).cs
        return float(cs[S_TH]), float(cs[S_OM])


__all__ = ["MODES", "Engine", "EngineConfig", "EngineStatus", "LoopTiming", "TelemetrySnapshot",
           "TelemetrySubscription"]
