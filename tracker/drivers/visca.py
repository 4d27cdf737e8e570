"""A real PTZ camera over VISCA (Sony's VISCA over IP on UDP, or raw VISCA on TCP) as a
:class:`tracker.drivers.camera.CameraDriver`.

:meth:`ViscaCamera.start` runs a supervisor task: connect (RESET the sequence numbers, ask the
power state), then every ``command_period_s`` ask the position and, while enabled with a
target, send one steering command: a Pan-tiltDrive from :mod:`tracker.drivers.camera_servo`
(``steering="speed"``, the default) or an AbsolutePosition when the target moved
(``steering="position"``). Both are sent without waiting for the answer of the previous cycle
(a lost one is superseded by the next); a stop is repeated for a few cycles.

No answer for ``link_lost_s`` latches the fault "link lost" (the console shows it), disables
the driver and reconnects with back-off (0.25 s doubling to 5 s); a reconnection first stops
the head (a speed drive sent before the loss would otherwise run on to the limits). After any
(re)connection the targets are forgotten: the camera does not move until enabled again and
given a target.

:meth:`ViscaCamera.take_over` lends the camera to a job that drives it itself (the console's
speed-table identification): until :meth:`ViscaCamera.hand_back` the supervisor sends no
steering and the engine's targets are ignored; at hand-back the targets are forgotten, so the
camera then goes back to the engine's next target (where it was held before the job).

With ``own_thread=True`` (the service) the supervisor and the link run on an event loop of
their own in a thread (:class:`tracker.drivers.loop_thread.LoopThread`), so the command cycle
keeps its period however busy the caller's event loop is (50 WebSocket viewers, a burst of
requests); the awaitable methods may still be called from the caller's loop.

The one-shot commands (absolute and relative moves, home, presets, zoom, inquiries) are
awaitable, sent with retransmission, and refuse to move the camera while disabled. Soft
limits (the engine's, within the camera's own range) clamp every absolute target, and speed
drives stop at them.

The soft limits are also the camera's own: on every (re)connection, and whenever
:meth:`ViscaCamera.set_limits` changes them, the driver sends Pan-tiltLimitSet for both
corners (rounded inward to whole counts; it replaces limits set on the camera by other means,
and a driver built without soft limits leaves them alone), so the camera's own loop stops the
head at them whatever the host does next: a command period late, a stalled process, a dead
one. A camera that answers with an error keeps running without them;
``describe()["camera_limits"]`` then says "refused" (and the log warns): the host is the only
guard (the speed law, and the hand-off below). Toward a limit, the last stretch of a speed
drive is handed to the camera's position loop too: once the head is within its stopping
distance (plus the latency and three command periods) of the limit, the driver sends an
AbsolutePosition to the limit (a rate drive) or to the target (clamped) at the drive's speed
instead of another Pan-tiltDrive, so the camera stops there by itself even without limits of
its own.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Coroutine, Mapping
from typing import Any, TypeVar

from tracker.drivers import visca_protocol as vp
from tracker.drivers.camera_profiles import CameraProfile
from tracker.drivers.camera_servo import STOP, AxisDrive, axis_drive, dead_band_rad, handoff_room_rad
from tracker.drivers.loop_thread import LoopThread
from tracker.drivers.motor import AXES, FaultLatch
from tracker.drivers.spec import DriverSpec
from tracker.drivers.visca_link import ViscaError, ViscaLink, open_link
from tracker.errors import ConfigError, DriverFault

BACKOFF_START_S = 0.25
BACKOFF_MAX_S = 5.0
STOP_REPEATS = 3
RATE_WINDOW = 25  # command cycles over which the achieved rate is measured
T = TypeVar("T")
log = logging.getLogger(__name__)


class ViscaCamera(FaultLatch):
    """The VISCA camera driver (see the module docstring)."""

    def __init__(
        self,
        spec: DriverSpec,
        profile: CameraProfile,
        limits_rad: Mapping[str, tuple[float, float]] | None = None,
        *,
        rate_hz: float = 25.0,
        steering: str = "speed",
        timeout_s: float = 0.1,
        retries: int = 8,
        link_lost_s: float = 1.0,
        link: ViscaLink | None = None,
        own_thread: bool = False,
    ) -> None:
        if spec.kind != "visca" or spec.host is None or spec.port is None or spec.transport is None:
            raise ConfigError(f"ViscaCamera needs a visca+udp/visca+tcp driver spec, got {spec.url!r}")
        if not 1.0 <= rate_hz <= 100.0:
            raise ConfigError(f"camera command rate {rate_hz!r} Hz must be in 1..100")
        if steering not in ("speed", "position"):
            raise ConfigError(f"camera steering {steering!r} is not 'speed' or 'position'")
        self.spec, self.profile, self.steering = spec, profile, steering
        self._period = 1.0 / rate_hz
        self._timeout, self._retries, self._link_lost_s = timeout_s, retries, link_lost_s
        self._link = link or open_link(spec.transport, spec.host, spec.port)
        self._limits = self._checked_limits(limits_rad)
        # The camera's own limits: "not programmed" (not connected yet), "programming", "set",
        # "refused" (an error reply: the host-side law is the only guard) or "failed" (no answer;
        # tried again next cycle). ``_limits_dirty``: the soft limits changed since programmed.
        self._owns_limits = limits_rad is not None  # without soft limits, leave the camera's alone
        self._camera_limits = "not programmed"
        self._camera_limits_error: str | None = None
        self._camera_limits_counts: dict[str, tuple[int, int]] = {}
        self._limits_dirty = False
        self._programming = False
        self._handoff: dict[str, tuple[int, float] | None] = {a: None for a in AXES}  # (direction, end)
        self._enabled = False
        self._faults: list[str] = []
        self._state = "stopped"
        self._last_error: str | None = None
        self._position: dict[str, float] = {a: 0.0 for a in AXES}
        self._position_t = 0.0  # monotonic time the position refers to
        self._have_position = False
        self._last_answer = 0.0
        self._target: dict[str, float | None] = {a: None for a in AXES}
        self._rate: dict[str, float] = {a: 0.0 for a in AXES}
        self._ff: dict[str, tuple[float, float] | None] = {a: None for a in AXES}  # (target, t) last cycle
        self._drive: dict[str, AxisDrive] = {a: STOP for a in AXES}
        # The head's speed as modelled: the commanded table speed reached at the profile's
        # acceleration (extrapolating with the commanded speed alone ran 0.2 deg past a limit).
        self._speed: dict[str, float] = {a: 0.0 for a in AXES}
        self._speed_t = 0.0
        self._sent_drive: tuple[AxisDrive, AxisDrive] | None = None
        self._sent_abs: tuple[float, float] | None = None
        self._stop_repeats = 0
        self._held_by: str | None = None  # a job the camera is lent to (take_over)
        self._task: asyncio.Task[None] | None = None
        self._own_thread = own_thread
        self._loop_thread: LoopThread | None = None  # own_thread: the link's loop, once started
        self._inflight: set[asyncio.Task[Any]] = set()
        self._cycle_times: list[float] = []
        self.cycles = 0
        self.missed_periods = 0  # command periods that passed without a cycle (a late loop)
        self.connects = 0

    # -- CameraDriver ---------------------------------------------------------------------------
    @property
    def axes(self) -> tuple[str, ...]:
        return AXES

    @property
    def sample_period_s(self) -> float:
        return 1e-3

    @property
    def command_period_s(self) -> float:
        return self._period

    @property
    def ready(self) -> bool:
        return self._state == "connected" and self._have_position

    @property
    def enabled(self) -> bool:
        return self._enabled

    @property
    def state(self) -> str:
        """"stopped", "connecting", "connected" or "reconnecting"."""
        return self._state

    def limits(self, axis: str) -> tuple[float, float]:
        """The limits the driver enforces on ``axis`` (rad, console frame)."""
        return self._limits[self._check_axis(axis)]

    def set_limits(self, limits_rad: Mapping[str, tuple[float, float]]) -> None:
        """New soft limits (rad, console frame; clipped to the camera's range): targets are
        clamped to them at once and the camera's own limits are programmed again on the next
        command cycle. ConfigError when an axis would be left no range."""
        limits = self._checked_limits({**self._limits, **limits_rad})
        self._limits = limits
        for axis in AXES:
            target = self._target[axis]
            if target is not None:
                self._target[axis] = min(max(target, limits[axis][0]), limits[axis][1])
        self._owns_limits = self._limits_dirty = True

    def camera_limit_counts(self) -> dict[str, tuple[int, int]]:
        """What Pan-tiltLimitSet sends for the soft limits: per corner ("up_right",
        "down_left"), (pan, tilt) in VISCA counts, rounded inward (never outside the limits)."""
        bounds = {}
        for axis in AXES:
            lo, hi = (self.profile.sign[axis] * v / self.profile.rad_per_count for v in self._limits[axis])
            lo, hi = min(lo, hi), max(lo, hi)  # VISCA frame, counts (not yet whole)
            bounds[axis] = (math.ceil(lo), math.floor(hi))
        return {"down_left": (bounds["pan"][0], bounds["tilt"][0]),
                "up_right": (bounds["pan"][1], bounds["tilt"][1])}

    def _checked_limits(
        self, limits_rad: Mapping[str, tuple[float, float]] | None
    ) -> dict[str, tuple[float, float]]:
        limits = {}
        for axis in AXES:
            lo, hi = self.profile.range_rad[axis]
            if limits_rad is not None and axis in limits_rad:
                want_lo, want_hi = limits_rad[axis]
                if not (math.isfinite(want_lo) and math.isfinite(want_hi)):
                    raise ConfigError(f"camera {axis} limits [{want_lo!r}, {want_hi!r}] rad are not finite")
                lo, hi = max(lo, want_lo), min(hi, want_hi)
            if not hi - lo > 2 * self.profile.rad_per_count:
                raise ConfigError(f"camera {axis} limits leave no range: [{lo:g}, {hi:g}] rad")
            limits[axis] = (lo, hi)
        return limits

    def enable(self) -> None:
        self.refuse_if_faulted()
        if not self.ready:
            raise DriverFault(f"cannot enable: camera {self.spec.url} is {self._state}, position unknown")
        self._forget_targets()
        self._enabled = True

    def disable(self) -> None:
        was = self._enabled
        self._enabled = False
        self._forget_targets()
        if was and self._state == "connected":
            self._stop_repeats = STOP_REPEATS

    @property
    def held_by(self) -> str | None:
        """The job the camera is lent to (``take_over``), or None."""
        return self._held_by

    def take_over(self, holder: str) -> None:
        """Lend the camera to ``holder`` (see the module docstring); DriverFault when it is lent
        already, disabled, faulted or not connected."""
        if self._held_by is not None:
            raise DriverFault(f"camera {self.spec.url} is already taken over by {self._held_by}")
        if not (self._enabled and self.ready):
            raise DriverFault(f"camera {self.spec.url} is not enabled and connected ({self._state})")
        self._forget_targets()
        self._drive = {a: STOP for a in AXES}
        self._held_by = holder

    def hand_back(self) -> None:
        """End ``take_over``: steering resumes toward the engine's next target."""
        self._held_by = None
        self._forget_targets()

    def set_target(self, axis: str, angle_rad: float) -> None:
        self._check_axis(axis)
        if not self._enabled or self._held_by is not None:
            return
        if not math.isfinite(angle_rad):
            self.latch_fault(f"{axis}: target {angle_rad!r} rad is not finite")
            return
        lo, hi = self._limits[axis]
        self._target[axis] = min(max(float(angle_rad), lo), hi)
        self._rate[axis] = 0.0

    def set_rate(self, axis: str, rate_rad_s: float) -> None:
        """A pure speed drive of ``axis`` (rad/s, console frame) that stops at the limits."""
        self._check_axis(axis)
        if not self._enabled:
            raise DriverFault(f"camera {self.spec.url} is disabled: enable it before driving")
        if self._held_by is not None:
            raise DriverFault(f"camera {self.spec.url} is taken over by {self._held_by}")
        if not math.isfinite(rate_rad_s):
            raise ConfigError(f"{axis} rate {rate_rad_s!r} rad/s is not finite")
        self._target[axis], self._rate[axis] = None, float(rate_rad_s)

    def read_encoder(self, axis: str) -> float:
        self._check_axis(axis)
        age = min(time.monotonic() - self._position_t, 2 * self._period) if self._have_position else 0.0
        return self._position[axis] + self._speed[axis] * age

    def start(self) -> None:
        if not self._own_thread:
            self._start_here()
            return
        if self._loop_thread is None or not self._loop_thread.running:
            self._loop_thread = LoopThread(f"camera {self.spec.url}")
        self._loop_thread.call(self._start_here)

    def _start_here(self) -> None:
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(
                self._supervise(), name=f"camera {self.spec.url}")

    async def _on_link_loop(self, coro: Coroutine[Any, Any, T]) -> T:
        """Await ``coro`` where the link lives: the camera's own loop (own_thread) or here."""
        lt = self._loop_thread
        return await coro if lt is None else await lt.run(coro)

    async def close(self) -> None:
        lt = self._loop_thread
        if lt is None:
            await self._close_here()
            return
        try:
            await lt.run(self._close_here())
        finally:
            self._loop_thread = None
            await asyncio.to_thread(lt.stop)

    async def _close_here(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        if self._state == "connected":
            with contextlib.suppress(DriverFault):
                await self._link.request(vp.pan_tilt_stop(), timeout_s=self._timeout, retries=2)
        for t in list(self._inflight):
            t.cancel()
        await self._link.close()
        self._state = "stopped"

    def describe(self) -> dict[str, Any]:
        stats = self._link.stats
        rate = None
        if len(self._cycle_times) > 1:
            rate = (len(self._cycle_times) - 1) / max(self._cycle_times[-1] - self._cycle_times[0], 1e-9)
        return {
            "kind": "visca",
            "url": self.spec.url,
            "profile": self.profile.name,
            "state": self._state,
            "steering": self.steering,
            "command_rate_hz": round(1.0 / self._period, 2),
            "achieved_rate_hz": None if rate is None else round(rate, 2),
            "missed_periods": self.missed_periods,
            "rtt_ms_median": _round(stats.rtt_percentile_ms(50)),
            "rtt_ms_p95": _round(stats.rtt_percentile_ms(95)),
            "sent": stats.sent,
            "retransmits": stats.retransmits,
            "timeouts": stats.timeouts,
            "sequence_resets": stats.sequence_resets,
            "completion_renewals": stats.completion_renewals,
            "connects": self.connects,
            "held_by": self._held_by,
            "last_error": self._last_error,
            "camera_limits": self._camera_limits_status(),
        }

    def _camera_limits_status(self) -> dict[str, Any]:
        """The camera's own limits: state, what guards the soft limits, and (once set) the
        limits programmed, in degrees of the console's frame."""
        out: dict[str, Any] = {
            "state": self._camera_limits,
            "guard": "camera and host" if self._camera_limits == "set" else "host only",
            "error": self._camera_limits_error,
        }
        counts = self._camera_limits_counts if self._camera_limits == "set" else {}
        if counts:
            for i, axis in enumerate(AXES):
                ends = sorted(math.degrees(self.profile.to_rad(axis, counts[c][i]))
                              for c in ("down_left", "up_right"))
                out[f"{axis}_deg"] = [round(v, 4) for v in ends]
        return out

    # -- one-shot commands ----------------------------------------------------------------------
    async def command(self, packet: bytes, *, completion: bool = False, timeout_s: float = 30.0) -> vp.Reply:
        """Send a VISCA command with retransmission (the ACK, or the Completion when asked)."""
        return await self._on_link_loop(self._link.request(
            packet, completion=completion, timeout_s=self._timeout, retries=self._retries,
            completion_timeout_s=timeout_s))

    async def inquire(self, packet: bytes) -> bytes:
        """Send a VISCA inquiry with retransmission; the answer's data bytes."""
        reply = await self._on_link_loop(
            self._link.request(packet, inquiry=True, timeout_s=self._timeout, retries=self._retries))
        return reply.data

    async def inquire_position(self) -> tuple[float, float]:
        """(pan, tilt) in rad, console frame, as the camera reports it now."""
        pan, tilt = vp.decode_pan_tilt(await self.inquire(vp.inquiry_pan_tilt()))
        return self.profile.to_rad("pan", pan), self.profile.to_rad("tilt", tilt)

    async def inquire_zoom(self) -> int:
        """The zoom position (counts, 0 = wide)."""
        return vp.decode_zoom(await self.inquire(vp.inquiry_zoom()))

    async def inquire_power(self) -> str:
        """"on", "standby" or "error"."""
        data = await self.inquire(vp.inquiry_power())
        return {vp.POWER_ON: "on", vp.POWER_STANDBY: "standby"}.get(data[0] if data else -1, "error")

    async def move_absolute(self, pan_rad: float, tilt_rad: float, *, wait: bool = True,
                            timeout_s: float = 30.0) -> tuple[float, float]:
        """Move to (pan, tilt) at full speed, clamped to the limits; returns the clamped target."""
        self._check_motion()
        pan_rad, tilt_rad = self._clamp("pan", pan_rad), self._clamp("tilt", tilt_rad)
        self._forget_targets()
        packet = vp.pan_tilt_position(
            len(self.profile.speeds_rad_s["pan"]), len(self.profile.speeds_rad_s["tilt"]),
            self._counts_inside("pan", pan_rad), self._counts_inside("tilt", tilt_rad))
        await self.command(packet, completion=wait, timeout_s=timeout_s)
        return pan_rad, tilt_rad

    async def move_relative(
        self, dpan_rad: float, dtilt_rad: float, *, wait: bool = True
    ) -> tuple[float, float]:
        """Move by (dpan, dtilt) from where the camera is; the end point is clamped to the limits."""
        pan, tilt = await self.inquire_position()
        return await self.move_absolute(pan + dpan_rad, tilt + dtilt_rad, wait=wait)

    async def stop(self) -> None:
        """Stop pan and tilt now (and forget the targets)."""
        self._forget_targets()
        await self.command(vp.pan_tilt_stop())

    async def home(self, *, wait: bool = True) -> None:
        """Pan-tiltDrive Home (0, 0), which lies inside any limits."""
        self._check_motion()
        self._forget_targets()
        await self.command(vp.pan_tilt_home(), completion=wait)

    async def preset_set(self, number: int) -> None:
        """Store the current direction and zoom as camera preset ``number`` (0-127)."""
        await self.command(vp.preset_set(number))

    async def preset_recall(self, number: int, *, wait: bool = True) -> None:
        """Recall camera preset ``number`` (stored by the camera, so within its own range)."""
        self._check_motion()
        self._forget_targets()
        await self.command(vp.preset_recall(number), completion=wait)

    async def zoom_to(self, counts: int, *, wait: bool = True) -> None:
        """Zoom to ``counts`` (clamped to 0..zoom_max)."""
        self._check_motion()
        await self.command(vp.zoom_direct(min(max(int(counts), 0), self.profile.zoom_max)), completion=wait)

    async def zoom_drive(self, speed: int) -> None:
        """Zoom toward tele (speed 1..8) or wide (-1..-8); 0 stops."""
        if speed:
            self._check_motion()
        await self.command(vp.zoom_drive(speed))

    async def zoom_stop(self) -> None:
        """Stop the zoom."""
        await self.command(vp.zoom_stop())

    # -- the supervisor ---------------------------------------------------------------------
    async def _supervise(self) -> None:
        backoff = BACKOFF_START_S
        while True:
            self._state = "connecting" if self.connects == 0 else "reconnecting"
            self._have_position = False
            try:
                await self._link.open()
                await self.inquire_power()
            except DriverFault as exc:
                self._last_error = str(exc)
                await self._link.close()
                await asyncio.sleep(backoff)
                backoff = min(2 * backoff, BACKOFF_MAX_S)
                continue
            try:
                if self._owns_limits:
                    await self._program_limits()  # before any motion: every (re)connection
                if self.connects > 0:
                    # The link was lost: a speed drive sent before may still be running (the stop
                    # the disable queued died with the link), so stop the head first.
                    await self._link.request(vp.pan_tilt_stop(), timeout_s=self._timeout,
                                             retries=self._retries)
            except DriverFault as exc:  # no answer: the link is not usable yet
                self._last_error = str(exc)
                await self._link.close()
                await asyncio.sleep(backoff)
                backoff = min(2 * backoff, BACKOFF_MAX_S)
                continue
            backoff = BACKOFF_START_S
            self.connects += 1
            self._forget_targets()  # never move on its own after a (re)connection
            self._drive = {a: STOP for a in AXES}
            self._speed = {a: 0.0 for a in AXES}
            self._state = "connected"
            self._last_answer = time.monotonic()
            lost = await self._cycle_until_lost()
            self._last_error = lost
            self.latch_fault(f"camera {self.spec.url}: link lost ({lost})")
            self._state = "reconnecting"
            for t in list(self._inflight):
                t.cancel()
            await self._link.close()

    async def _cycle_until_lost(self) -> str:
        loop = asyncio.get_running_loop()
        next_t = loop.time()
        previous: float | None = None  # this connection's previous cycle
        while True:
            now = time.monotonic()
            if now - self._last_answer > self._link_lost_s:
                return f"no answer for {now - self._last_answer:.1f} s"
            self.cycles += 1
            if previous is not None:  # whole periods that passed without a cycle
                self.missed_periods += max(0, int((now - previous) / self._period + 1e-6) - 1)
            previous = now
            self._cycle_times = [*self._cycle_times[-RATE_WINDOW:], now]
            if (self._limits_dirty or self._camera_limits == "failed") and not self._programming:
                self._spawn(self._program_limits(quiet=True))
            self._spawn(self._poll_position())
            self._spawn(self._steer())
            next_t += self._period
            delay = next_t - loop.time()
            if delay < -self._period:  # fell behind: drop cycles rather than burst
                next_t, delay = loop.time(), 0.0
            await asyncio.sleep(max(0.0, delay))

    async def _program_limits(self, *, quiet: bool = False) -> None:
        """Send Pan-tiltLimitSet for both corners (see the module docstring). An error reply
        leaves the camera without them ("refused"); no answer raises LinkTimeout, or with
        ``quiet`` marks them "failed" (tried again next cycle)."""
        self._programming, self._limits_dirty = True, False
        self._camera_limits = "programming"
        counts = self.camera_limit_counts()
        packets = [vp.pan_tilt_limit_set(vp.LIMIT_DOWN_LEFT, *counts["down_left"]),
                   vp.pan_tilt_limit_set(vp.LIMIT_UP_RIGHT, *counts["up_right"])]
        try:
            try:
                for packet in packets:
                    await self._link.request(packet, completion=True, timeout_s=self._timeout,
                                             retries=self._retries, completion_timeout_s=2.0)
            except ViscaError as exc:
                if exc.code != vp.ERR_NOT_EXECUTABLE:
                    raise
                # New limits that cross the old ones (an upper corner below the old lower one)
                # are not executable one corner at a time: clear both, then set both.
                for corner in (vp.LIMIT_DOWN_LEFT, vp.LIMIT_UP_RIGHT):
                    await self._link.request(vp.pan_tilt_limit_clear(corner), completion=True,
                                             timeout_s=self._timeout, retries=self._retries,
                                             completion_timeout_s=2.0)
                for packet in packets:
                    await self._link.request(packet, completion=True, timeout_s=self._timeout,
                                             retries=self._retries, completion_timeout_s=2.0)
        except ViscaError as exc:
            self._camera_limits, self._camera_limits_error = "refused", str(exc)
            log.warning("camera %s refused its pan-tilt limits (%s): the host (speed law and "
                        "hand-off) is the only guard of the soft limits", self.spec.url, exc)
        except DriverFault as exc:
            self._camera_limits, self._camera_limits_error = "failed", str(exc)
            if not quiet:
                raise
        else:
            self._camera_limits, self._camera_limits_error = "set", None
            self._camera_limits_counts = counts
            log.info("camera %s: pan-tilt limits set to %s", self.spec.url, counts)
        finally:
            self._programming = False

    def _spawn(self, coro: Any) -> None:
        task = asyncio.get_running_loop().create_task(coro)
        self._inflight.add(task)
        task.add_done_callback(self._inflight.discard)

    async def _poll_position(self) -> None:
        sent = time.monotonic()
        try:
            reply = await self._link.request(vp.inquiry_pan_tilt(), inquiry=True,
                                             timeout_s=2 * self._period, retries=0)
            pan, tilt = vp.decode_pan_tilt(reply.data)
        except DriverFault as exc:
            self._last_error = str(exc)
            return
        now = time.monotonic()
        self._last_answer = now
        measured_at = 0.5 * (sent + now)
        if measured_at >= self._position_t:
            self._position = {"pan": self.profile.to_rad("pan", pan),
                              "tilt": self.profile.to_rad("tilt", tilt)}
            self._position_t, self._have_position = measured_at, True

    async def _steer(self) -> None:
        packet = self._steering_packet()
        if packet is None:
            return
        try:
            await self._link.request(packet, timeout_s=2 * self._period, retries=0)
            self._last_answer = time.monotonic()
        except DriverFault as exc:
            self._last_error = str(exc)
            self._sent_drive = self._sent_abs = None  # send again next cycle

    def _steering_packet(self) -> bytes | None:
        now = time.monotonic()
        step = self.profile.accel_rad_s2 * min(now - self._speed_t, 2 * self._period)
        self._speed_t = now
        for axis in AXES:
            dv = self._drive[axis].speed_rad_s - self._speed[axis]
            self._speed[axis] += max(-step, min(dv, step))
        if self._held_by is not None and self._enabled:  # the holder steers (a disable still stops)
            self._drive = {a: STOP for a in AXES}
            return None
        if not (self._enabled and self._have_position):
            self._drive = {a: STOP for a in AXES}
            if self._stop_repeats > 0:
                self._stop_repeats -= 1
                return vp.pan_tilt_stop()
            return None
        if self.steering == "position" and all(self._target[a] is not None for a in AXES):
            self._drive = {a: STOP for a in AXES}
            return self._position_packet()
        latency = (self._link.stats.rtt_percentile_ms(50) or 0.0) * 1e-3
        for axis in AXES:
            target = self._target[axis]
            rate = self._rate[axis]
            if target is not None:
                last = self._ff[axis]
                rate = 0.0 if last is None else (target - last[0]) / max(now - last[1], 1e-3)
                rate = max(-self.profile.max_speed_rad_s(axis), min(rate, self.profile.max_speed_rad_s(axis)))
                self._ff[axis] = (target, now)
            elif rate == 0.0:
                self._drive[axis] = STOP
                continue
            self._drive[axis] = axis_drive(
                self.profile, axis, position_rad=self.read_encoder(axis), target_rad=target,
                rate_rad_s=rate, limits_rad=self._limits[axis], period_s=self._period, latency_s=latency)
        handing_off, packet = self._handoff_packet(latency)
        if handing_off:
            self._stop_repeats = STOP_REPEATS
            return packet
        pan, tilt = self._drive["pan"], self._drive["tilt"]
        moving = pan.direction != 0 or tilt.direction != 0
        if moving:
            self._stop_repeats = STOP_REPEATS
        elif self._stop_repeats > 0:
            self._stop_repeats -= 1
        else:
            return None
        self._sent_drive = (pan, tilt)
        self._sent_abs = None
        return self._drive_packet(pan, tilt)

    def _handoff_packet(self, latency_s: float) -> tuple[bool, bytes | None]:
        """The last stretch toward a limit for the camera's own position loop (see the module
        docstring): (True, an AbsolutePosition or None when the same one went out already), or
        (False, None) to keep steering by speed. A hand-off holds while the axis' drive keeps its
        direction or stops; a reversal, or a rate or target forgotten, ends it. The other axis
        goes to its target, to its limit ahead when driven by rate, or stops where it would."""
        ends: dict[str, float] = {}
        for axis in AXES:
            drive, target, held = self._drive[axis], self._target[axis], self._handoff[axis]
            forgotten = target is None and self._rate[axis] == 0.0
            if held is not None and (drive.direction == -held[0] or forgotten):
                held = None
            direction = drive.direction or (held[0] if held is not None else 0)
            if direction == 0:
                continue
            lo, hi = self._limits[axis]
            limit = hi if direction > 0 else lo
            if held is None:
                speed = max(abs(drive.speed_rad_s), abs(self._speed[axis]))
                room = min(direction * (limit - self.read_encoder(axis)),
                           direction * (limit - self._position_ahead(axis)))
                reach = handoff_room_rad(self.profile, axis, speed, period_s=self._period,
                                         latency_s=latency_s)
                if room > reach:
                    continue
            end = limit if target is None else target
            held = (direction, end)
            self._handoff[axis] = held
            ends[axis] = end
        for axis in AXES:
            if axis not in ends:
                self._handoff[axis] = None
        if not ends:
            return False, None
        codes = {}
        for axis in AXES:
            drive = self._drive[axis]
            if axis not in ends:
                target = self._target[axis]
                lo, hi = self._limits[axis]
                speed = self._speed[axis]
                stop_at = self.read_encoder(axis) + speed * abs(speed) / (2.0 * self.profile.accel_rad_s2)
                ends[axis] = (target if target is not None
                              else (hi if drive.direction > 0 else lo) if drive.direction != 0
                              else min(max(stop_at, lo), hi))
            codes[axis] = self._handoff_code(axis, drive)
        end_pan, end_tilt = ends["pan"], ends["tilt"]
        dead = {a: dead_band_rad(self.profile, a, self._period) for a in AXES}
        if self._sent_abs is not None and abs(end_pan - self._sent_abs[0]) < dead["pan"] \
                and abs(end_tilt - self._sent_abs[1]) < dead["tilt"]:
            return True, None
        self._sent_abs = (end_pan, end_tilt)
        self._sent_drive = None
        counts = self._counts_inside("pan", end_pan), self._counts_inside("tilt", end_tilt)
        return True, vp.pan_tilt_position(codes["pan"], codes["tilt"], *counts)

    def _position_ahead(self, axis: str) -> float:
        """Where the head may be by now: the last reported angle advanced by the modelled speed
        over the report's whole age (up to 1 s), not two periods as :meth:`read_encoder`; after
        the host stalled, the head ran on at that speed (with the stall's missed cycles, the
        hand-off then comes on the first cycle back instead of an RTT later)."""
        age = min(time.monotonic() - self._position_t, 1.0) if self._have_position else 0.0
        return self._position[axis] + self._speed[axis] * age

    def _handoff_code(self, axis: str, drive: AxisDrive) -> int:
        """The speed code of a handed-off move: the drive's, or the one the head still runs at."""
        if drive.direction != 0:
            return drive.code
        return self.profile.speed_code(axis, abs(self._speed[axis]))

    def _drive_packet(self, pan: AxisDrive, tilt: AxisDrive) -> bytes:
        # console -> VISCA frame: VISCA pan positive is right (direction byte 2), tilt up (1).
        visca_pan = pan.direction * self.profile.sign["pan"]
        visca_tilt = tilt.direction * self.profile.sign["tilt"]
        pan_dir = vp.PAN_STOP if visca_pan == 0 else (vp.PAN_RIGHT if visca_pan > 0 else vp.PAN_LEFT)
        tilt_dir = vp.TILT_STOP if visca_tilt == 0 else (vp.TILT_UP if visca_tilt > 0 else vp.TILT_DOWN)
        return vp.pan_tilt_drive(pan.code, tilt.code, pan_dir, tilt_dir)

    def _position_packet(self) -> bytes | None:
        pan, tilt = self._target["pan"], self._target["tilt"]
        assert pan is not None and tilt is not None
        dead = {a: dead_band_rad(self.profile, a, self._period) for a in AXES}
        if self._sent_abs is not None and abs(pan - self._sent_abs[0]) < dead["pan"] \
                and abs(tilt - self._sent_abs[1]) < dead["tilt"]:
            return None
        self._sent_abs = (pan, tilt)
        return vp.pan_tilt_position(
            len(self.profile.speeds_rad_s["pan"]), len(self.profile.speeds_rad_s["tilt"]),
            self._counts_inside("pan", pan), self._counts_inside("tilt", tilt))

    # -- helpers ----------------------------------------------------------------------------
    def _forget_targets(self) -> None:
        for a in AXES:
            self._target[a], self._rate[a], self._ff[a] = None, 0.0, None
            self._handoff[a] = None
        self._sent_abs = None
        self._stop_repeats = 0

    def _counts_inside(self, axis: str, angle_rad: float) -> int:
        """The VISCA counts of ``angle_rad`` (within the limits), moved one count inward when
        rounding to the nearest would land past a limit."""
        counts = self.profile.to_counts(axis, angle_rad)
        lo, hi = self._limits[axis]
        at = self.profile.to_rad(axis, counts)
        if at > hi or at < lo:
            counts -= self.profile.sign[axis] * (1 if at > hi else -1)
        return counts

    def _check_motion(self) -> None:
        if not self._enabled:
            raise DriverFault(f"camera {self.spec.url} is disabled"
                              + (f" (fault: {'; '.join(self._faults)})" if self._faults else ""))

    def _clamp(self, axis: str, angle_rad: float) -> float:
        if not math.isfinite(angle_rad):
            raise ConfigError(f"{axis} target {angle_rad!r} rad is not finite")
        lo, hi = self._limits[axis]
        return min(max(float(angle_rad), lo), hi)

    def _check_axis(self, axis: str) -> str:
        if axis not in AXES:
            raise ConfigError(f"unknown axis {axis!r}; the camera has {', '.join(AXES)}")
        return axis


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 2)
