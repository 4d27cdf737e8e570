"""The serial motor controller board in Python, on the rig's twin: what the emulator runs.

It is the protocol's reference behaviour (docs/serial-protocol.md): a line in, one line out,
the command held until the next ``C`` line or until the watchdog expires, both encoders
counted on the motor shaft. The twin is :func:`tracker.plant.simulate.advance` on the pan and
tilt presets (plus any hidden effects of a rig config), advanced in 1 ms samples up to the
moment each line arrives, the command zero-order held as a board's PWM update would hold it;
mechanical end stops sit 5° past the soft limits.

Limits the board enforces (``L``/``B``, the doc's C): at every 1 ms tick, per axis, an axis
moving outward inside its braking zone gets the full reverse command, and a command pushing
further out past a limit is replaced by 0 — whatever the host does or fails to do.
"""

from __future__ import annotations

import math
import secrets
import threading
import time
from collections.abc import Callable, Mapping

import numpy as np

from tracker.control.closed_loop import history_length
from tracker.drivers import motor_protocol as mp
from tracker.drivers.motor import AXES
from tracker.drivers.sim import HARD_STOP_MARGIN_RAD, rig_models
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel
from tracker.plant.params import MOTOR_GEAR_RATIO, PULLEY_RATIO, get_preset
from tracker.plant.simulate import advance, initial_state, pack_params

DT_S = 1e-3
WATCHDOG_DEFAULT_MS = 100
WATCHDOG_RANGE_MS = (10, 2000)
# The seed's Pittman GM8724: 500 lines decoded x4 on the motor, 6.3:1 gear and 2.7:1 pulley.
SEED_COUNTS_PER_REV = 2000
SEED_GEAR_RATIO = MOTOR_GEAR_RATIO * PULLEY_RATIO
VMAX_MV = 10_000
TICKS_PER_S = 1000  # the board's limit check runs once per twin sample (1 ms)
COUNT_RANGE = (-(2**31), 2**31 - 1)  # signed 32-bit counts


def limit_output(cmd_mv: int, count: int, v: int, lo: int, hi: int, brake_cps2: int, vmax_mv: int) -> int:
    """The board's limit check for one axis at one tick (docs/serial-protocol.md, ``limit()``):
    ``v`` the counts moved since the last tick; the output in mV."""
    if brake_cps2 > 0 and v != 0:
        vc = v * TICKS_PER_S  # counts per second
        zone = vc * vc // (2 * brake_cps2) + abs(v)  # braking distance plus one tick's travel
        if v > 0 and count + zone >= hi:
            return -vmax_mv
        if v < 0 and count - zone <= lo:
            return vmax_mv
    if (count >= hi and cmd_mv > 0) or (count <= lo and cmd_mv < 0):
        return 0
    return cmd_mv


class RigTwin:
    """Both axes of the DC rig, advanced one 1 ms sample at a time under held commands (V)."""

    def __init__(self, models: Mapping[str, AxisModel] | None = None) -> None:
        self.models = dict(rig_models()) if models is None else dict(models)
        self._p = {a: pack_params(self.models[a], DT_S, quantize=False) for a in AXES}
        self._x = {a: initial_state() for a in AXES}
        self._hist = {a: np.zeros(history_length(self._p[a], DT_S)) for a in AXES}
        self._stop = {a: get_preset(a).soft_limit_rad + HARD_STOP_MARGIN_RAD for a in AXES}
        advance(initial_state(), self._p["pan"], np.zeros(1), 0, DT_S, 0.0)  # compile now, not mid-line

    def step(self, volts: Mapping[str, float]) -> None:
        """One sample with ``volts[axis]`` held."""
        for a in AXES:
            h, x = self._hist[a], self._x[a]
            h[:-1] = h[1:]
            h[-1] = volts[a]
            advance(x, self._p[a], h, h.size - 1, DT_S, 0.0)
            if abs(x[2]) > self._stop[a]:  # the end stop: the load halts there
                x[:] = initial_state(math.copysign(self._stop[a], x[2]))

    def motor_rad(self, axis: str) -> float:
        """The motor-side angle expressed at the load (rad): what the encoder counts."""
        return float(self._x[axis][0])

    def load_rad(self, axis: str) -> float:
        """Where the load really points (rad)."""
        return float(self._x[axis][2])

    def velocity_rad_s(self, axis: str) -> float:
        return float(self._x[axis][1])

    def set_angle(self, axis: str, theta_rad: float) -> None:
        """Place ``axis`` at rest at ``theta_rad`` (test set-up)."""
        self._x[axis][:] = initial_state(theta_rad)


class MotorBoard:
    """The board's firmware: parse a line, act, answer (see the module docstring).

    ``clock`` gives seconds; the board's time starts at 0 when it is made (its power-up).
    Thread-safe: the emulator's thread handles lines while a test inspects the twin.
    """

    def __init__(
        self,
        twin: RigTwin | None = None,
        *,
        counts_per_rev: int = SEED_COUNTS_PER_REV,
        gear_ratio: float = SEED_GEAR_RATIO,
        vmax_mv: int = VMAX_MV,
        board_id: str = "emulator",
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        if counts_per_rev <= 0 or gear_ratio <= 0 or vmax_mv <= 0:
            raise ConfigError(
                f"board: cpr {counts_per_rev}, gear {gear_ratio}, vmax {vmax_mv} mV must be > 0")
        self.twin = twin or RigTwin()
        self.hello = mp.Hello(mp.PROTOCOL_VERSION, "3dat-mc-emu", board_id,
                              (counts_per_rev, counts_per_rev), vmax_mv, WATCHDOG_DEFAULT_MS,
                              secrets.token_hex(4))
        self._counts_per_rad = counts_per_rev * gear_ratio / (2 * math.pi)
        # Counts start at 0 wherever the rig stands at power-up (a restarted board on the same
        # twin, as a real board reset on the same mount, counts from there).
        self._zero = {a: self.twin.motor_rad(a) for a in AXES}
        self._clock = clock
        self._t0 = clock()
        self._k = 0  # twin samples done
        self._lock = threading.Lock()
        self.armed = False
        self.watchdog_tripped = False
        self.watchdog_ms = WATCHDOG_DEFAULT_MS
        self.command_mv = {a: 0 for a in AXES}
        self.output_mv = {a: 0 for a in AXES}  # what the amplifier gets: the command after the limits
        self.limits_counts: dict[str, tuple[int, int]] | None = None  # L; None: off
        self.brake_cps2 = {a: 0 for a in AXES}  # B; 0: no braking zone
        self._prev_count = {a: self.counts(a) for a in AXES}
        self.limit_brakes = {a: 0 for a in AXES}  # ticks the braking zone reversed the output
        self.limit_refusals = {a: 0 for a in AXES}  # ticks a command past a limit was zeroed
        self._last_command_s = 0.0
        self.lines = 0
        self.errors = 0
        self.watchdog_trips = 0

    def now_s(self) -> float:
        """The board's time since power-up (s)."""
        return self._clock() - self._t0

    def counts(self, axis: str) -> int:
        """The encoder count of ``axis`` (quadrature, motor shaft, 0 where it stood at power-up)."""
        return int(math.floor((self.twin.motor_rad(axis) - self._zero[axis]) * self._counts_per_rad + 0.5))

    def catch_up(self) -> None:
        """Advance the twin to now (the watchdog included)."""
        with self._lock:
            self._catch_up(self.now_s())

    def _catch_up(self, now_s: float) -> None:
        while (self._k + 1) * DT_S <= now_s:
            t = self._k * DT_S
            if self.armed and t - self._last_command_s > self.watchdog_ms * 1e-3:
                self._disarm(watchdog=True)
            self._limit_tick()
            self.twin.step({a: self.output_mv[a] * 1e-3 for a in AXES})
            self._k += 1

    def _limit_tick(self) -> None:
        """The doc's ``limit()`` per axis: the outputs for this tick. The braking zone acts armed
        or not (it only takes outward speed away: a coasting axis after a watchdog trip too)."""
        lims = self.limits_counts
        for a in AXES:
            c = self.counts(a)
            v, self._prev_count[a] = c - self._prev_count[a], c
            cmd = self.command_mv[a]
            if lims is None:
                self.output_mv[a] = cmd
                continue
            out = limit_output(cmd, c, v, lims[a][0], lims[a][1], self.brake_cps2[a], self.hello.vmax_mv)
            if out != cmd:
                if abs(out) == self.hello.vmax_mv and out * v < 0:
                    self.limit_brakes[a] += 1
                else:
                    self.limit_refusals[a] += 1
            self.output_mv[a] = out

    def _disarm(self, watchdog: bool = False) -> None:
        self.armed = False
        self.command_mv = {a: 0 for a in AXES}
        if watchdog:
            self.watchdog_tripped = True
            self.watchdog_trips += 1

    def handle(self, raw: bytes) -> bytes:
        """Answer one line (with or without its newline)."""
        with self._lock:
            now = self.now_s()
            self._catch_up(now)
            self.lines += 1
            try:
                line = mp.parse_line(raw)
                return self._act(line, now)
            except mp.FramingError as exc:
                self.errors += 1
                return mp.frame("-" if exc.seq is None else exc.seq, "ERR", exc.code, exc.text)

    def _act(self, line: mp.Line, now: float) -> bytes:
        seq = "-" if line.seq is None else line.seq
        verb, args = line.verb, line.args
        if verb == "H" and not args:
            return mp.hello_reply(line.seq or 0, self.hello)
        if verb == "E" and not args:
            return self._counts_reply(seq, now)
        if verb == "C":
            values = _ints(args, 2)
            if values is None:
                raise mp.FramingError(mp.ERR_BAD_ARGUMENT, "C needs two integers (mV)", line.seq)
            vmax = self.hello.vmax_mv
            if any(abs(v) > vmax for v in values):
                raise mp.FramingError(mp.ERR_OUT_OF_RANGE, f"command beyond +-{vmax} mV", line.seq)
            self._last_command_s = now
            if self.armed:
                self.command_mv = dict(zip(AXES, values, strict=True))
            return self._counts_reply(seq, now)
        if verb == "A":
            values = _ints(args, 1)
            if values is None or values[0] not in (0, 1):
                raise mp.FramingError(mp.ERR_BAD_ARGUMENT, "A needs 0 or 1", line.seq)
            self._disarm()
            if values[0] == 1:
                self.armed, self.watchdog_tripped, self._last_command_s = True, False, now
            return mp.frame(seq, "OK")
        if verb == "W":
            values = _ints(args, 1)
            if values is None:
                raise mp.FramingError(mp.ERR_BAD_ARGUMENT, "W needs milliseconds", line.seq)
            lo, hi = WATCHDOG_RANGE_MS
            if not lo <= values[0] <= hi:
                raise mp.FramingError(mp.ERR_OUT_OF_RANGE, f"watchdog {values[0]} ms outside {lo}..{hi}",
                                      line.seq)
            self.watchdog_ms = values[0]
            return mp.frame(seq, "OK")
        if verb == "L":
            if not args:
                self.limits_counts = None
                return mp.frame(seq, "OK")
            values = _ints(args, 4)
            if values is None:
                raise mp.FramingError(mp.ERR_BAD_ARGUMENT, "L needs 4 counts (or none)", line.seq)
            if (not all(COUNT_RANGE[0] <= v <= COUNT_RANGE[1] for v in values)
                    or values[0] >= values[1] or values[2] >= values[3]):
                raise mp.FramingError(mp.ERR_OUT_OF_RANGE, "limits need lo < hi in 32-bit counts", line.seq)
            self.limits_counts = {"pan": (values[0], values[1]), "tilt": (values[2], values[3])}
            return mp.frame(seq, "OK")
        if verb == "B":
            values = _ints(args, 2)
            if values is None:
                raise mp.FramingError(mp.ERR_BAD_ARGUMENT, "B needs 2 decelerations (counts/s^2)", line.seq)
            if not all(0 <= v <= COUNT_RANGE[1] for v in values):
                raise mp.FramingError(mp.ERR_OUT_OF_RANGE, "deceleration outside 0..2^31-1", line.seq)
            self.brake_cps2 = dict(zip(AXES, values, strict=True))
            return mp.frame(seq, "OK")
        if verb in ("H", "E"):
            raise mp.FramingError(mp.ERR_BAD_ARGUMENT, f"{verb} takes no arguments", line.seq)
        raise mp.FramingError(mp.ERR_UNKNOWN_VERB, f"unknown verb {verb[:8]}", line.seq)

    def _counts_reply(self, seq: int | str, now: float) -> bytes:
        flags = (mp.FLAG_ARMED if self.armed else 0) | (mp.FLAG_WATCHDOG if self.watchdog_tripped else 0)
        t_us = int(now * 1e6) % 2**32
        return mp.frame(seq, "E", t_us, self.counts("pan"), self.counts("tilt"), f"{flags:X}")

    def set_angle(self, axis: str, theta_rad: float) -> None:
        """Place ``axis`` of the twin at rest at ``theta_rad`` (test set-up)."""
        with self._lock:
            self._catch_up(self.now_s())
            self.twin.set_angle(axis, theta_rad)
            self._prev_count[axis] = self.counts(axis)  # a placement is no speed


def _ints(args: tuple[str, ...], n: int) -> list[int] | None:
    if len(args) != n:
        return None
    try:
        return [int(a, 10) for a in args]
    except ValueError:
        return None
