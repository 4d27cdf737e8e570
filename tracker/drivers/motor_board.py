"""The serial motor controller board in Python, on the rig's twin: what the emulator runs.

It is the protocol's reference behaviour (docs/serial-protocol.md): a line in, one line out,
the command held until the next ``C`` line or until the watchdog expires, both encoders
counted on the motor shaft. The twin is :func:`tracker.plant.simulate.advance` on the pan and
tilt presets (plus any hidden effects of a rig config), advanced in 1 ms samples up to the
moment each line arrives, the command zero-order held as a board's PWM update would hold it;
mechanical end stops sit 5° past the soft limits.
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
            self.twin.step({a: self.command_mv[a] * 1e-3 for a in AXES})
            self._k += 1

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


def _ints(args: tuple[str, ...], n: int) -> list[int] | None:
    if len(args) != n:
        return None
    try:
        return [int(a, 10) for a in args]
    except ValueError:
        return None
