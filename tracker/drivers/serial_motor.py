"""A DC rig behind a motor controller board on a serial port, as a
:class:`tracker.drivers.motor.MotorDriver` (the protocol: docs/serial-protocol.md).

Who talks when: a supervisor thread opens the port, says hello (counts per revolution, the
command limit, a boot nonce), sets the board's watchdog and disarms it; while connected it
only reads the counts when nobody else has for 0.1 s (so a stopped loop still sees the port
go). The control loop's thread does the sample exchanges itself in :meth:`tick` (a hand-off to
another thread would cost a GIL switch per sample): it waits for the sample's due time, sends
``C pan_mV tilt_mV`` (``E`` while disabled) and reads the counts the board answers with; the
next :meth:`read_encoder` returns them. A lock keeps the two threads' lines apart.

Angles: load rad = counts·2π/(cpr·gear ratio), counts from the board's hello and the gear
ratio per axis from the settings; the board counts from 0 at power-up, so the mount must be
powered up at its centre. A board that restarted (a new boot nonce) is re-referenced so the
angle continues from the last one read.

Safety: the soft limits are enforced here too — a command that drives further past a limit
line is sent as 0 V, and past the end stop (limit + 5°) a fault latches. Host timing can never
be trusted for a limit, so the board enforces them as well (``L``/``B``, docs/serial-protocol.md):
on every connection and whenever the limits change the driver programs them in counts, 2 mrad
inside and rounded inward, with a braking deceleration from the model (half of K·Vmax/J); the
board then brakes an axis whose stopping distance reaches a limit and refuses commands further
out, at its own tick, however late the host is. A board that answers ``L`` or ``B`` with an
error is shown in status as "limits enforced by the host only"; then, while an axis is lent
to an experiment, the board's watchdog is shortened to ``LENT_WATCHDOG_MS``, the longest stall
the friction sweep's capped moves are made for (a longer one stops the sweep instead of letting
it run on), and the URL's watchdog comes back with the hand-back. A board that enforces the
limits keeps the URL's watchdog (a loaded machine's pty has delivered a line 0.26 s late).
No answer for
``link_lost_s`` (the URL's ``link_lost_ms``, 0.25 s by default), or a port that fails,
latches "link lost" and disables; the supervisor then reconnects with back-off (0.25 s
doubling to 5 s) and the board stays disarmed until the fault is cleared and the driver
enabled again. If the host stops commanding altogether, the board's watchdog zeroes the
command and disarms; the next reply says so and a fault latches.

Lending (:meth:`SerialMotorDriver.take_over`): a job hands in an experiment as a generator
that yields the volts for the next sample and is sent what that sample read (angle rad, the
board's time s): the friction-ID sweep, :func:`tracker.workbench.experiments.friction_id.friction_sweep`.
The control loop's own thread runs it, one step per exchange, so it keeps the loop's clock
whatever else the machine does (a hand-off to the job's thread each sample was late on one
sample in ten on a loaded machine). Only the lent axis is the job's (``held_axis``): the loop's
commands for it are ignored and it holds that axis wherever it goes, starting afresh from there
when it comes back, while it goes on steering the other (a tilt axis left at 0 V would droop).
The soft limits and faults apply to the experiment's commands as to the loop's; a fault or an
error in the experiment ends the lending. The returned future holds the result.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Generator, Mapping
from concurrent.futures import Future
from typing import Any

from tracker.drivers import motor_protocol as mp
from tracker.drivers.motor import AXES, FaultLatch
from tracker.drivers.serial_port import ReplyTimeout, SerialPort
from tracker.drivers.sim import HARD_STOP_MARGIN_RAD
from tracker.drivers.spec import SERIAL_LINK_LOST_MS, DriverSpec
from tracker.errors import ConfigError, DriverFault
from tracker.realtime import sleep_until

BACKOFF_START_S = 0.25
BACKOFF_MAX_S = 5.0
IDLE_READ_S = 0.1
MAX_BEHIND_S = 0.1
HELLO_WAIT_S = 3.0  # an Arduino restarts when its port opens: ~2 s of boot loader first
RTT_WINDOW = 500
LENT_WATCHDOG_MS = 200  # the watchdog while an experiment has an axis of a host-only-limits board
BRAKE_SHARE = 0.5  # of the model's K·Vmax/J: the deceleration the board's braking zone counts on
# The board's lines sit this far inside the driver's: an axis at rest next to its line reads a
# speed of 0 counts a tick while the full command moves it a few counts in two ticks (the
# one-count speed resolution), so the board stops up to ~3 counts (0.6 mrad) past its line.
BOARD_INSET_RAD = 0.002
BOARD_LIMITS = "limits enforced by the board"
HOST_LIMITS = "limits enforced by the host only"
# An experiment run by the control loop (take_over): yields volts, is sent (angle rad, board time s).
Experiment = Generator[float, tuple[float, float], Any]


class _BoardError(Exception):
    pass


class SerialMotorDriver(FaultLatch):
    """The serial motor controller driver (see the module docstring)."""

    def __init__(
        self,
        spec: DriverSpec,
        gear_ratio: Mapping[str, float] | None = None,
        limits_rad: Mapping[str, tuple[float, float]] | None = None,
        *,
        link_lost_s: float | None = None,
        reply_timeout_s: float | None = None,
        open_port: Callable[[str, int], SerialPort] = SerialPort,
    ) -> None:
        if spec.kind != "serial" or spec.path is None or not spec.baud or not spec.rate_hz:
            raise ConfigError(f"SerialMotorDriver needs a serial:// driver spec, got {spec.url!r}")
        from tracker.drivers.motor_board import SEED_GEAR_RATIO
        from tracker.plant.params import get_preset

        self.spec = spec
        self._dt = 1.0 / spec.rate_hz
        self._gear = {a: float((gear_ratio or {}).get(a, SEED_GEAR_RATIO)) for a in AXES}
        for a, g in self._gear.items():
            if not (math.isfinite(g) and g > 0):
                raise ConfigError(f"serial driver: {a} gear ratio {g!r} must be a positive number")
        self._limits = {a: (limits_rad or {}).get(a) or (-get_preset(a).soft_limit_rad,
                                                        get_preset(a).soft_limit_rad) for a in AXES}
        self._stops = {a: max(abs(lo), abs(hi)) + HARD_STOP_MARGIN_RAD
                       for a, (lo, hi) in self._limits.items()}
        # The board's braking zone counts on BRAKE_SHARE·K·Vmax/J (rad/s² at the load): K/J here.
        self._accel_per_v = {a: get_preset(a).gain_nm_per_v / get_preset(a).inertia_kg_m2 for a in AXES}
        self._limits_dirty = True  # the board's limits to be (re)programmed
        self._board_limits: str | None = None  # BOARD_LIMITS, HOST_LIMITS, None before a connection
        self.board_limit_counts: dict[str, tuple[int, int]] | None = None
        self._url_wd_ms = spec.watchdog_ms or 100  # the watchdog asked for, outside lending
        self._want_wd_ms = self._url_wd_ms
        self._board_wd_ms: int | None = None
        self._link_lost_s = (float(link_lost_s) if link_lost_s is not None
                             else (spec.link_lost_ms or SERIAL_LINK_LOST_MS) / 1e3)
        self._timeout = reply_timeout_s or max(0.005, 3 * self._dt)
        self._open_port = open_port
        self._port: SerialPort | None = None
        self._lock = threading.Lock()  # one exchange on the line at a time
        self._wake = threading.Event()
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._state = "stopped"
        self._seq = 0
        self.hello: mp.Hello | None = None
        self._rad_per_count = {a: 0.0 for a in AXES}
        self._ref = {a: (0, 0.0) for a in AXES}  # (counts, rad) the angle is counted from
        self._counts = {a: 0 for a in AXES}
        self._angle = {a: 0.0 for a in AXES}
        self._have_angle = False
        self._u = {a: 0.0 for a in AXES}
        self._enabled = False
        self._board_armed = False
        self._faults: list[str] = []
        self._next_due: float | None = None
        self._failing_since: float | None = None  # the first unanswered request of a run of them
        self._last_exchange = 0.0
        self._last_error: str | None = None
        self._rtts: deque[float] = deque(maxlen=RTT_WINDOW)
        self._sample_times: deque[float] = deque(maxlen=RTT_WINDOW)
        self._held_by: str | None = None
        self._lent: tuple[str, Experiment, Future[Any]] | None = None  # take_over's axis, experiment
        self._lent_volts = 0.0  # the experiment's command for the next exchange
        self._lent_t = 0.0  # the board time of the reading the experiment was last sent
        self.samples = 0  # sample exchanges the control loop made (tick)
        self.board_t_us = 0  # the latest reading's time stamp as the board sent it (µs, 32 bits)
        self._board_s = 0.0  # the board's clock unwrapped, continued across reconnects (s)
        self._board_last_us: int | None = None
        self.exchanges = self.timeouts = self.errors = self.late_samples = 0
        self.refused = {a: 0 for a in AXES}
        self.connects = 0
        self.re_referenced = 0
        self.max_lateness_s = 0.0

    # -- MotorDriver -----------------------------------------------------------------------------
    @property
    def axes(self) -> tuple[str, ...]:
        return AXES

    @property
    def sample_period_s(self) -> float:
        return self._dt

    @property
    def sample_time_s(self) -> float:
        return self._board_s

    @property
    def enabled(self) -> bool:
        return self._enabled

    @property
    def held_axis(self) -> str | None:
        """The axis lent to a job (:meth:`take_over`), or None."""
        return None if self._lent is None else self._lent[0]

    @property
    def held_by(self) -> str | None:
        """The job the rig is lent to (:meth:`take_over`), or None."""
        return self._held_by

    @property
    def state(self) -> str:
        """"stopped", "connecting", "connected" or "reconnecting"."""
        return self._state

    @property
    def ready(self) -> bool:
        """Connected, with the counts read since."""
        return self._state == "connected" and self._have_angle

    def limits(self, axis: str) -> tuple[float, float]:
        """The limit lines the driver enforces on ``axis`` (rad)."""
        return self._limits[self._check_axis(axis)]

    def set_limits(self, axis: str, lower_rad: float, upper_rad: float) -> None:
        """New limit lines for ``axis`` (rad, within the end stops): enforced here at once and
        programmed into the board at the next exchange."""
        self._check_axis(axis)
        lo, hi = float(lower_rad), float(upper_rad)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi
                and max(-lo, hi) < self._stops[axis]):
            raise ConfigError(f"{axis}: limits {lower_rad!r}..{upper_rad!r} rad must be finite, "
                              f"lower < upper, within the end stops ±{self._stops[axis]:.4f} rad")
        self._limits[axis] = (lo, hi)
        self._limits_dirty = True

    @property
    def board_limits(self) -> str | None:
        """Who enforces the limits: BOARD_LIMITS, HOST_LIMITS (the board refused ``L``), or None
        before the first connection."""
        return self._board_limits

    def enable(self) -> None:
        self.refuse_if_faulted()
        if self._held_by is not None:
            raise DriverFault(f"{self.spec.url} is taken over by {self._held_by}")
        if not self.ready:
            raise DriverFault(f"cannot enable: {self.spec.url} is {self._state}, position unknown")
        self._u = {a: 0.0 for a in AXES}
        self._enabled = True  # the next exchange arms the board

    def disable(self) -> None:
        self._enabled = False
        self._u = {a: 0.0 for a in AXES}

    def command(self, axis: str, volts: float) -> None:
        if self._lent is None or axis != self._lent[0]:
            self._set_command(axis, volts)

    def _set_command(self, axis: str, volts: float) -> None:
        self._check_axis(axis)
        if not math.isfinite(volts):
            self.latch_fault(f"{axis}: command {volts!r} V is not finite")
            return
        self._u[axis] = float(volts) if self._enabled else 0.0

    def take_over(self, holder: str, axis: str, experiment: Experiment) -> Future[Any]:
        """Lend ``axis`` to ``holder``'s ``experiment`` (see the module docstring), run by the
        control loop's exchanges until it returns, fails, or :meth:`hand_back`; the future
        gets its return value or its exception. DriverFault when the rig is lent already,
        faulted, disabled or not connected."""
        self._check_axis(axis)
        self.refuse_if_faulted()
        if self._held_by is not None:
            raise DriverFault(f"{self.spec.url} is already taken over by {self._held_by}")
        if not (self._enabled and self.ready):
            raise DriverFault(f"{self.spec.url} must be connected and enabled ({self._state}"
                              f"{'' if self._enabled else ', disabled'})")
        done: Future[Any] = Future()
        done.set_running_or_notify_cancel()
        self._u[axis] = 0.0
        try:
            first = next(experiment)
        except BaseException as exc:  # noqa: BLE001 - handed to the future
            done.set_exception(exc)
            return done
        if self._board_limits != BOARD_LIMITS:
            self._want_wd_ms = min(LENT_WATCHDOG_MS, self.spec.watchdog_ms or LENT_WATCHDOG_MS)
        self._lent = (axis, experiment, done)
        self._lent_volts = first
        self._lent_t = self._board_s
        self._held_by = holder
        return done

    def hand_back(self, error: BaseException | None = None) -> None:
        """End :meth:`take_over` (0 V; the control loop steers again from where the axes are).
        An experiment still running is closed, its future given ``error`` (default: DriverFault
        saying it was stopped)."""
        lent, self._lent = self._lent, None
        if lent is not None:
            self._u[lent[0]] = 0.0
        self._held_by = None
        self._want_wd_ms = self._url_wd_ms
        if lent is not None:
            _, experiment, done = lent
            # From another thread while the loop's thread runs a step: that step is its last
            # (the lending is over); the generator cannot be closed mid-step.
            with contextlib.suppress(ValueError):
                experiment.close()
            if not done.done():
                done.set_exception(error or DriverFault(f"{self.spec.url}: the experiment was stopped"))

    def _lent_step(self) -> None:
        """After an exchange: the experiment's next volts from this sample's reading."""
        lent = self._lent
        if lent is None:
            return
        axis, experiment, done = lent
        if self._faults or not self._enabled:
            why = "; ".join(self._faults) or "the rig was disabled"
            self.hand_back(DriverFault(f"{self._held_by} stopped on {axis}: {why}"))
            return
        if self._board_s == self._lent_t:  # no new reading (a timed-out exchange): same volts again
            return
        self._lent_t = self._board_s
        try:
            self._lent_volts = experiment.send((self._angle[axis], self._board_s))
            return
        except StopIteration as stop:
            result, error = stop.value, None
        except BaseException as exc:  # noqa: BLE001 - the experiment's error is its job's, not the loop's
            result, error = None, exc
        self._lent = None
        self._u[axis] = 0.0
        self._held_by = None
        self._want_wd_ms = self._url_wd_ms
        if not done.done():  # not already ended by hand_back from another thread
            if error is None:
                done.set_result(result)
            else:
                done.set_exception(error)

    def read_encoder(self, axis: str) -> float:
        return self._angle[self._check_axis(axis)]

    def tick(self) -> None:
        """Wait for the sample's due time, then send the command and read the counts.

        Samples are due on the grid of whole periods of ``time.perf_counter`` (the engine's
        loop paces its chunks on the same grid, so the two clocks agree); a late one goes at
        once, and more than ``MAX_BEHIND_S`` behind the schedule restarts at the last grid
        point."""
        now = time.perf_counter()
        due = self._next_due
        if due is None or now - due > MAX_BEHIND_S:
            due = math.floor(now / self._dt) * self._dt
        elif now < due:
            sleep_until(due, 0.0)  # no busy-wait: the line's own jitter is larger
        late = time.perf_counter() - due
        if late > self._dt:
            self.late_samples += 1
        self.max_lateness_s = max(self.max_lateness_s, late)
        self._next_due = due + self._dt
        self._sample_times.append(time.perf_counter())
        lent = self._lent
        if lent is not None:
            self._set_command(lent[0], self._lent_volts)
        with self._lock:
            if self._port is not None and self._state == "connected":
                self._cycle(idle=False)
        self.samples += 1
        self._lent_step()

    # -- life cycle ------------------------------------------------------------------------------
    def start(self) -> None:
        """Connect (and reconnect) in a background thread."""
        if self._thread is None or not self._thread.is_alive():
            self._closing.clear()
            self._state = "connecting"
            self._thread = threading.Thread(target=self._supervise, name=f"serial {self.spec.path}",
                                            daemon=True)
            self._thread.start()

    def wait_ready(self, timeout_s: float) -> None:
        """Block until connected with a position; DriverFault naming the last error otherwise."""
        end = time.monotonic() + timeout_s
        while not self.ready:
            if time.monotonic() > end:
                raise DriverFault(f"{self.spec.url}: not ready after {timeout_s:g} s "
                                  f"({self._state}; {self._last_error or 'no answer'})")
            time.sleep(0.01)

    def close(self) -> None:
        """Disarm the board, close the port and stop the supervisor."""
        self._enabled = False
        self._closing.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        with self._lock:
            if self._port is not None and self._state == "connected":
                with contextlib.suppress(OSError, ReplyTimeout, _BoardError, DriverFault):
                    self._request("A", 0)
            self._drop_port()
        self._state = "stopped"

    def describe(self) -> dict[str, Any]:
        rtts = sorted(self._rtts)
        times = list(self._sample_times)
        rate = (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 and times[-1] > times[0] else None
        h = self.hello
        return {
            "kind": "serial",
            "url": self.spec.url,
            "state": self._state,
            "held_by": self._held_by,
            "held_axis": self.held_axis,
            "board": None if h is None else f"{h.board} {h.board_id} (protocol {h.protocol})",
            "counts_per_rev": None if h is None else list(h.counts_per_rev),
            "gear_ratio": dict(self._gear),
            "rate_hz": self.spec.rate_hz,
            "achieved_rate_hz": None if rate is None else round(rate, 1),
            "rtt_ms_median": _ms(rtts[len(rtts) // 2]) if rtts else None,
            "rtt_ms_p95": _ms(rtts[int(0.95 * (len(rtts) - 1))]) if rtts else None,
            "watchdog_ms": self.spec.watchdog_ms,
            "board_watchdog_ms": self._board_wd_ms,
            "board_limits": self._board_limits,
            "board_limit_counts": None if self.board_limit_counts is None else
            {a: list(v) for a, v in self.board_limit_counts.items()},
            "exchanges": self.exchanges,
            "timeouts": self.timeouts,
            "errors": self.errors,
            "late_samples": self.late_samples,
            "max_lateness_ms": _ms(self.max_lateness_s),
            "refused_at_limits": dict(self.refused),
            "connects": self.connects,
            "re_referenced": self.re_referenced,
            "last_error": self._last_error,
        }

    # -- the line --------------------------------------------------------------------------------
    def _request(self, verb: str, *args: object, timeout_s: float | None = None) -> mp.Line:
        """One exchange (the lock held): send, then the reply with our sequence number."""
        port = self._port
        if port is None:
            raise OSError("port closed")
        self._seq = (self._seq + 1) % 256
        seq = self._seq
        sent = time.perf_counter()
        port.write(mp.frame(seq, verb, *args))
        deadline = sent + (timeout_s or self._timeout)
        while True:
            try:
                line = mp.parse_line(port.read_line(deadline), mp.MAX_REPLY)
            except mp.FramingError as exc:  # a garbled reply: ours is lost, wait for the timeout
                self.errors += 1
                self._last_error = f"garbled reply: {exc.text}"
                continue
            except ReplyTimeout:
                self.timeouts += 1
                raise
            if line.verb == "ERR" and line.seq in (seq, None):
                self.errors += 1
                self._last_error = f"board: {verb} refused: ERR {' '.join(line.args)}"
                raise _BoardError(self._last_error)
            if line.seq == seq:
                now = time.perf_counter()
                self._rtts.append(now - sent)
                self.exchanges += 1
                self._last_exchange = now
                self._failing_since = None
                return line

    def _cycle(self, idle: bool) -> None:
        """Arm or disarm as wanted, then send the command (or read); the lock held."""
        where = self.spec.url
        want = self._enabled  # read once: enable()/disable() may come from another thread
        try:
            if self._limits_dirty:
                self._program_limits()
            wd = self._want_wd_ms
            if wd != self._board_wd_ms:
                self._request("W", wd)
                self._board_wd_ms = wd
            if want != self._board_armed and not (idle and want):
                self._request("A", int(want))
                self._board_armed = want
            expect_armed = want and self._board_armed
            if expect_armed and not idle:  # only the control loop feeds the board's watchdog
                vmax = self.hello.vmax_mv if self.hello else 0
                mv = [max(-vmax, min(vmax, int(round(1e3 * self._limited(a, self._u[a]))))) for a in AXES]
                reply = self._request("C", *mv)
            else:
                reply = self._request("E")
            self._absorb(mp.parse_counts(reply, where), expect_armed)
        except ReplyTimeout:
            # Lost when requests have gone unanswered for link_lost_s, not when this process
            # was too busy to ask (a stall of our own is not the board's silence).
            now = time.perf_counter()
            if self._failing_since is None:
                self._failing_since = now - self._timeout
            elif now - self._failing_since > self._link_lost_s:
                self._lose(f"no answer for {self._link_lost_s:g} s")
        except (OSError, DriverFault) as exc:
            self._lose(str(exc))
        except _BoardError as exc:
            self.latch_fault(f"{where}: {exc}")

    def _program_limits(self, timeout_s: float | None = None) -> None:
        """Send the board the limit lines in counts, rounded inward, and the braking zone's
        deceleration (the lock held, the counts' reference known). A board that refuses ``L`` or
        ``B`` leaves the limits to the host (shown in status); the link's errors propagate."""
        counts: dict[str, tuple[int, int]] = {}
        brake: list[int] = []
        vmax_v = (self.hello.vmax_mv if self.hello else 10_000) / 1e3
        for a in AXES:
            rpc = self._rad_per_count[a]
            ref_c, ref_rad = self._ref[a]
            lo, hi = self._limits[a]
            counts[a] = (ref_c + math.ceil((lo + BOARD_INSET_RAD - ref_rad) / rpc - 1e-9),
                         ref_c + math.floor((hi - BOARD_INSET_RAD - ref_rad) / rpc + 1e-9))
            brake.append(max(1, int(BRAKE_SHARE * self._accel_per_v[a] * vmax_v / rpc)))
        try:
            self._request("B", *brake, timeout_s=timeout_s)
            self._request("L", *counts["pan"], *counts["tilt"], timeout_s=timeout_s)
        except _BoardError as exc:
            self._limits_dirty = False
            self._board_limits = HOST_LIMITS
            self.board_limit_counts = None
            self._last_error = f"{exc} ({HOST_LIMITS})"
            return
        self._limits_dirty = False
        self._board_limits = BOARD_LIMITS
        self.board_limit_counts = counts

    def _limited(self, axis: str, volts: float) -> float:
        lo, hi = self._limits[axis]
        th = self._angle[axis]
        if (th >= hi and volts > 0.0) or (th <= lo and volts < 0.0):
            self.refused[axis] += 1
            return 0.0
        return volts

    def _absorb(self, counts: mp.Counts, expect_armed: bool = False) -> None:
        if self._board_last_us is not None:  # the 32-bit µs counter wraps every 71.6 min
            self._board_s += ((counts.t_us - self._board_last_us) % 2**32) * 1e-6
        self._board_last_us = self.board_t_us = counts.t_us
        for a, c in (("pan", counts.pan), ("tilt", counts.tilt)):
            ref_c, ref_rad = self._ref[a]
            self._counts[a] = c
            self._angle[a] = ref_rad + (c - ref_c) * self._rad_per_count[a]
            if abs(self._angle[a]) > self._stops[a]:
                self.latch_fault(f"{a}: over-travel at {math.degrees(self._angle[a]):.1f}° "
                                 f"(end stop ±{math.degrees(self._stops[a]):.1f}°)")
        self._have_angle = True
        self._board_armed = counts.armed
        if expect_armed and self._enabled and not counts.armed:
            wd_ms = self._board_wd_ms or self.spec.watchdog_ms
            why = (f"the board's watchdog zeroed the command (no command for {wd_ms} ms)"
                   if counts.watchdog_tripped else "the board disarmed itself")
            self.latch_fault(f"{self.spec.url}: {why}")

    def _lose(self, reason: str) -> None:
        self._last_error = reason
        self.latch_fault(f"{self.spec.url}: link lost ({reason})")
        self._drop_port()
        self._state = "reconnecting"
        self._wake.set()

    def _drop_port(self) -> None:
        if self._port is not None:
            self._port.close()
            self._port = None
        self._board_armed = False
        self._board_wd_ms = None

    # -- the supervisor --------------------------------------------------------------------------
    def _supervise(self) -> None:
        backoff = BACKOFF_START_S
        while not self._closing.is_set():
            if self._state == "connected":
                self._wake.wait(IDLE_READ_S)
                self._wake.clear()
                if self._state == "connected" and time.perf_counter() - self._last_exchange > IDLE_READ_S:
                    with self._lock:
                        if self._port is not None and self._state == "connected":
                            self._cycle(idle=True)
                continue
            try:
                self._connect()
                backoff = BACKOFF_START_S
            except (OSError, ReplyTimeout, _BoardError, DriverFault) as exc:
                self._last_error = str(exc) or type(exc).__name__.strip("_").lower()
                with self._lock:
                    self._drop_port()
                self._state = "reconnecting" if self.connects else "connecting"
                self._closing.wait(backoff)
                backoff = min(2 * backoff, BACKOFF_MAX_S)

    def _connect(self) -> None:
        port = self._open_port(self.spec.path or "", self.spec.baud or 0)
        with self._lock:
            self._port = port
            self._have_angle = False
            hello = self._hello()
            wd = self._want_wd_ms
            self._request("W", wd, timeout_s=0.5)
            self._board_wd_ms = wd
            self._request("A", 0, timeout_s=0.5)
            self._board_armed = False
            counts = mp.parse_counts(self._request("E", timeout_s=0.5), self.spec.url)
            rebooted = self.hello is not None and hello.boot != self.hello.boot
            self.hello = hello
            for i, a in enumerate(AXES):
                self._rad_per_count[a] = 2 * math.pi / (hello.counts_per_rev[i] * self._gear[a])
                c = counts.pan if a == "pan" else counts.tilt
                if rebooted:  # counts restarted from 0 where the axis stood: carry the angle on
                    self._ref[a] = (c, self._angle[a])
            self.re_referenced += int(rebooted)
            self._board_last_us = None  # a new link's clock (maybe a restarted board's) goes on from here
            self._absorb(counts)
            self._program_limits(0.5)  # a new link may be a new board: its limits again
            self._failing_since = None
            self._next_due = None
            self.connects += 1
            self._state = "connected"

    def _hello(self) -> mp.Hello:
        end = time.perf_counter() + HELLO_WAIT_S
        while True:
            assert self._port is not None
            self._port.flush_input()
            try:
                return mp.parse_hello(self._request("H", timeout_s=0.25), self.spec.url)
            except (ReplyTimeout, _BoardError):
                if time.perf_counter() > end or self._closing.is_set():
                    raise DriverFault(f"{self.spec.url}: no hello from the board") from None

    def _check_axis(self, axis: str) -> str:
        if axis not in self._angle:
            raise ConfigError(f"unknown axis {axis!r}; the rig has {', '.join(AXES)}")
        return axis


def _ms(seconds: float) -> float:
    return round(1e3 * seconds, 3)

