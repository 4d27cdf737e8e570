"""The seed's friction-identification experiment, automated on any motor driver (seed §3.1, App. B/C).

For each direction: a slow voltage ramp from rest finds the break-away voltage (stiction shows
as break-away torque above the Coulomb intercept; a transport delay does not change it on a
slow ramp). Then constant voltages, each started with the seed's 10 V break-away pulse, give
one point (average velocity, torque K·V) each; a line per direction (the seed's ``polyfit``,
App. C) gives the viscous slope and the Coulomb intercept.

A mount has end stops, and the twin's time constant J/b (≈ 3 s on pan) is longer than a pass
over the travel, so a run may end before the velocity is steady. The pulse is therefore sized
to bring the axis near the speed the voltage will hold (shortened from 0.25 s when that is
enough), each pass starts at one end of the travel, and each point's torque is corrected for
whatever acceleration remains: τ = K·V − J·α̅ (α̅ = 0 at a true steady state, where this is
exactly the seed's method). J comes from the model (datasheet/CAD), as in the seed.

The positioning moves between runs are capped so that they cannot pass the limit lines on
their own (:func:`_push_cap`): a host that stalls leaves the board holding the last command,
so every command is at most what the axis can be held at for a whole stall (the serial
board's watchdog while the rig is lent, ``STALL_S``) and then coast to rest on friction
alone before the line — with the model's K, J and 0.8 of its friction.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tracker.drivers.motor import MotorDriver
from tracker.errors import DataError, DriverFault, JobCancelled
from tracker.plant.params import get_preset
from tracker.units import AMPLIFIER_LIMIT_V

FloatArray = NDArray[np.float64]
SEED_PULSE_V = 10.0
SEED_PULSE_S = 0.25
SETTLE_S = 0.03
MIN_MEASURE_S = 0.15
RAMP_V_PER_S = 0.3
TRAVEL_FRACTION = 0.85
MAX_RUN_S = 1.0  # measured part of a run; long enough to average, short enough to be quick
# The positioning moves: the longest host stall they must survive on their own (the serial
# driver's board watchdog while an axis is lent, tracker.drivers.serial_motor.LENT_WATCHDOG_MS,
# on a board that does not enforce limits: longer, and the board disarms and the axis coasts;
# a board that enforces them brakes before its lines whatever the stall), the share of the
# model's friction counted on to stop it, and a margin before the limit line for the encoder's
# compliance and rounding.
STALL_S = 0.2
FRICTION_SHARE = 0.8
LINE_MARGIN_RAD = 0.01


@dataclass(frozen=True, slots=True)
class FrictionPoint:
    """One constant-voltage run: the voltage, the mean velocity and the friction torque there."""

    volts: float
    velocity_rad_s: float
    torque_nm: float
    accel_rad_s2: float
    moved: bool
    too_fast: bool = False

    def to_dict(self) -> dict[str, object]:
        return {
            "volts": self.volts,
            "velocity_rad_s": self.velocity_rad_s,
            "torque_nm": self.torque_nm,
            "accel_rad_s2": self.accel_rad_s2,
            "moved": self.moved,
            "too_fast": self.too_fast,
        }


@dataclass(frozen=True, slots=True)
class FrictionLine:
    """torque = viscous·ω + sign·coulomb for one direction, with standard errors."""

    viscous_nm_s_per_rad: float
    coulomb_nm: float
    viscous_se: float
    coulomb_se: float
    points: int


@dataclass(frozen=True, slots=True)
class FrictionResult:
    """Per-direction friction lines, break-away torques and the torque-vs-velocity points."""

    axis: str
    gain_nm_per_v: float
    positive: FrictionLine
    negative: FrictionLine
    breakaway_positive_nm: float
    breakaway_negative_nm: float
    points: tuple[FrictionPoint, ...]
    simulated_s: float

    @property
    def params(self) -> dict[str, float]:
        """Model parameters: positive direction in the base names, negative in the asymmetries."""
        return {
            "viscous.b": self.positive.viscous_nm_s_per_rad,
            "coulomb.torque": self.positive.coulomb_nm,
            "viscous_asymmetry.negative": self.negative.viscous_nm_s_per_rad,
            "coulomb_asymmetry.negative": self.negative.coulomb_nm,
        }

    def stiction_excess_nm(self) -> tuple[float, float]:
        """Break-away torque above the Coulomb intercept, (positive, negative) direction."""
        return (
            self.breakaway_positive_nm - self.positive.coulomb_nm,
            self.breakaway_negative_nm - self.negative.coulomb_nm,
        )

    def shows_stiction(self) -> bool:
        """True when break-away needs clearly more torque than Coulomb in both directions."""
        ep, en = self.stiction_excess_nm()
        tol_p = max(3 * self.positive.coulomb_se, 0.05 * self.positive.coulomb_nm)
        tol_n = max(3 * self.negative.coulomb_se, 0.05 * self.negative.coulomb_nm)
        return ep > tol_p and en > tol_n

    def to_dict(self) -> dict[str, object]:
        def line(li: FrictionLine) -> dict[str, float]:
            return {
                "viscous_nm_s_per_rad": li.viscous_nm_s_per_rad,
                "coulomb_nm": li.coulomb_nm,
                "viscous_se": li.viscous_se,
                "coulomb_se": li.coulomb_se,
                "points": li.points,
            }

        ep, en = self.stiction_excess_nm()
        return {
            "axis": self.axis,
            "gain_nm_per_v": self.gain_nm_per_v,
            "positive": line(self.positive),
            "negative": line(self.negative),
            "breakaway_nm": {"positive": self.breakaway_positive_nm, "negative": self.breakaway_negative_nm},
            "stiction_excess_nm": {"positive": ep, "negative": en},
            "shows_stiction": self.shows_stiction(),
            "params": self.params,
            "plot": {
                "velocity_rad_s": [p.velocity_rad_s for p in self.points if p.moved],
                "torque_nm": [p.torque_nm for p in self.points if p.moved],
            },
            "points": [p.to_dict() for p in self.points],
            "simulated_s": self.simulated_s,
        }


# The sweep is a generator: it yields the volts for the next sample and is sent back what that
# sample read, (angle rad, the device's time s). Whoever owns the rig's clock drives it: the
# sync loop of :func:`run_friction_id` on any MotorDriver, or a serial rig's control loop, one
# sample per exchange, while the rig is lent to a job (tracker.drivers.serial_motor).
Reading = tuple[float, float]
Sweep = Generator[float, Reading, "FrictionResult"]


@dataclass(frozen=True, slots=True)
class _Mover:
    """What a positioning move must respect: the axis' K (N·m/V), J (kg·m²), model Coulomb
    friction (N·m), the limit lines (rad) and the stall (s) it must survive."""

    gain: float
    inertia: float
    coulomb: float
    limits: tuple[float, float]
    stall_s: float


def _push_cap(mv: _Mover, speed_out: float, room: float, dt: float) -> float:
    """The largest command (V, pushing outward; negative: the brake it needs) that keeps the
    axis inside a line ``room`` rad away when it moves outward at ``speed_out`` rad/s.

    Worst case: the command is held for the stall S (+ one sample), the board then disarms
    and the axis coasts on friction alone at a_c = share·Coulomb/J. With the outward
    acceleration a held: v·S + a·S²/2 + (v + a·S)²/(2·a_c) ≤ room, a quadratic in a whose larger
    root is the cap; if even stopping within the stall overshoots (v·S/2 > room), the
    deceleration that stops in the room. Then V = (J·a + share·c)/K: the viscous term is left
    out (it falls as a braked axis slows, so counting today's b·v would overstate the brake),
    and so only helps. An axis moving inward is taken as at rest (its inward travel and the
    time it takes to turn only help).
    """
    v = max(speed_out, 0.0)
    d = max(room - LINE_MARGIN_RAD, 1e-6)
    s = mv.stall_s + dt
    a_c = FRICTION_SHARE * mv.coulomb / mv.inertia
    if v * s / 2 > d:
        a = -v * v / (2 * d)
    else:
        c2, c1, c0 = s * s / (2 * a_c), s * s / 2 + v * s / a_c, v * s + v * v / (2 * a_c) - d
        a = (-c1 + math.sqrt(max(c1 * c1 - 4 * c2 * c0, 0.0))) / (2 * c2)
    return (mv.inertia * a + FRICTION_SHARE * mv.coulomb) / mv.gain


class _Axis:
    """One axis as the sweep sees it: the latest reading, the sample count, cancel checks."""

    def __init__(self, axis: str, dt: float, first: Reading, cancel: Callable[[], bool] | None) -> None:
        self.axis, self.dt, self.cancel = axis, dt, cancel
        self.th, self.t = first
        self.ticks = 0

    def step(self, volts: float) -> Generator[float, Reading, float]:
        """One sample at ``volts`` (clipped to the amplifier); the angle it read."""
        if self.cancel is not None and self.ticks % 100 == 0 and self.cancel():
            raise JobCancelled("friction identification cancelled")
        self.th, self.t = yield max(-AMPLIFIER_LIMIT_V, min(AMPLIFIER_LIMIT_V, float(volts)))
        self.ticks += 1
        return self.th

    def hold(self, seconds: float) -> Generator[float, Reading, float]:
        th = self.th
        for _ in range(int(round(seconds / self.dt))):
            th = yield from self.step(0.0)
        return th

    def move_to(self, target_rad: float, mv: _Mover, max_s: float = 4.0) -> Generator[float, Reading, float]:
        """PD move to ``target_rad`` (20 rad/s loop), each command capped by :func:`_push_cap`
        towards either line, then let it settle with 0 V. Velocity from the board's time stamps (a late
        sample is not a fast axis)."""
        wn = 20.0
        kp, kd = wn * wn * mv.inertia / mv.gain, 2 * 0.8 * wn * mv.inertia / mv.gain
        lo, hi = mv.limits
        th = prev = self.th
        t_prev = self.t
        vel = 0.0
        still = 0
        for _ in range(int(round(max_s / self.dt))):
            u = kp * (target_rad - th) - kd * vel
            up, down = _push_cap(mv, vel, hi - th, self.dt), _push_cap(mv, -vel, th - lo, self.dt)
            # When the two cannot both hold (a fast axis near a line), the line it heads for wins.
            u = min(max(u, -down), up) if vel >= 0 else max(min(u, up), -down)
            th = yield from self.step(u)
            span = self.t - t_prev if self.t > t_prev else self.dt
            a = math.exp(-2 * math.pi * 50.0 * span)
            vel = a * vel + (1 - a) * (th - prev) / span
            still = still + 1 if th == prev else 0
            prev, t_prev = th, self.t
            # Friction leaves a small steady error without integral action: near and still is done.
            if abs(target_rad - th) < 0.15 and still * self.dt > 0.02:
                break
        return (yield from self.hold(0.05))


def _breakaway_volts(
    ax: _Axis, s: float, start_v: float, step_rad: float
) -> Generator[float, Reading, float]:
    """Ramp the command from ``start_v`` in direction ``s`` until the axis moves; return |V|."""
    th0 = ax.th
    v = start_v
    for _ in range(int(round(AMPLIFIER_LIMIT_V / RAMP_V_PER_S / ax.dt))):
        v += RAMP_V_PER_S * ax.dt
        th = yield from ax.step(s * v)
        if s * (th - th0) > step_rad:  # moved the ramp's way (not the last move's drift)
            yield from ax.step(0.0)
            return v
    raise DataError(
        f"{ax.axis}: the axis did not move with {AMPLIFIER_LIMIT_V:g} V; is the amplifier enabled?"
    )


def _constant_voltage_run(
    ax: _Axis,
    s: float,
    volts: float,
    pulse_s: float,
    end_rad: float,
    gain: float,
    inertia: float,
    max_s: float,
) -> Generator[float, Reading, FrictionPoint]:
    """The seed's run: 10 V pulse, then constant ``volts``; mean velocity and corrected torque."""
    n_pulse = max(1, int(round(pulse_s / ax.dt)))
    for _ in range(n_pulse):
        yield from ax.step(s * SEED_PULSE_V)
    for _ in range(int(round(SETTLE_S / ax.dt))):
        yield from ax.step(s * volts)
    th = [ax.th]
    times = [ax.t]  # the device's time stamps: a host that slips does not bend them
    for _ in range(int(round(max_s / ax.dt))):
        th.append((yield from ax.step(s * volts)))
        times.append(ax.t)
        if s * (th[-1] - end_rad) > 0:
            break
        if len(th) > 100 and th[-1] == th[-51]:
            break  # stopped: friction won
    yield from ax.step(0.0)
    y = np.asarray(th)
    t = np.asarray(times)
    stopped = y.size > 100 and y[-1] == y[-51]
    if stopped or abs(y[-1] - y[0]) < 0.02:
        return FrictionPoint(s * volts, 0.0, gain * s * volts, 0.0, False)
    c2, c1, _ = np.polyfit(t - t.mean(), y, 2)
    accel = 2 * c2
    torque = gain * s * volts - inertia * accel
    # Too fast: crossed the travel before a settled measurement; kept for the voltage search.
    fast = bool(t[-1] - t[0] < MIN_MEASURE_S - ax.dt)
    return FrictionPoint(s * volts, float(c1), float(torque), float(accel), not fast, fast)


def _fit_line(points: list[FrictionPoint], s: float) -> FrictionLine:
    pts = [p for p in points if p.moved and p.velocity_rad_s * s > 0]
    if len(pts) < 3:
        raise DataError(
            f"friction ID: only {len(pts)} moving runs in the {'positive' if s > 0 else 'negative'} "
            "direction; need 3. Widen the voltage range, or look for a position-dependent torque "
            "(a gravity unbalance): the sweep assumes the axis keeps moving at a constant voltage"
        )
    w = np.array([p.velocity_rad_s for p in pts])
    tq = np.array([p.torque_nm for p in pts])
    coef, cov = np.polyfit(w, tq, 1, cov=True) if len(pts) > 3 else (np.polyfit(w, tq, 1), np.zeros((2, 2)))
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    return FrictionLine(float(coef[0]), float(s * coef[1]), float(se[0]), float(se[1]), len(pts))


def run_friction_id(
    driver: MotorDriver,
    axis: str,
    gain_nm_per_v: float | None = None,
    inertia_kg_m2: float | None = None,
    voltages_per_direction: int = 10,
    max_speed_rad_s: float = 3.0,
    pulse_s: float = SEED_PULSE_S,
    travel_rad: float | None = None,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> FrictionResult:
    """Run the friction-ID experiment on ``axis`` of ``driver``, sample by sample here.

    Parameters
    ----------
    driver : any :class:`tracker.drivers.motor.MotorDriver` (the simulated rig or hardware).
    axis : "pan" or "tilt"; its preset gives K, J and the travel unless given.
    gain_nm_per_v, inertia_kg_m2 : K (N·m/V) and J (kg·m²) of the axis.
    voltages_per_direction : constant-voltage runs per direction.
    max_speed_rad_s : fastest run (the travel must hold a settled measurement at this speed).
    pulse_s : the seed's break-away pulse length (shortened when a shorter pulse reaches the
        run's speed).
    travel_rad : usable travel either side of zero (default: 85 % of the soft limit).
    progress : called with the fraction done; cancel : polled, True raises JobCancelled.

    Returns
    -------
    FrictionResult
    """
    driver.enable()
    try:
        first = (driver.read_encoder(axis), driver.sample_time_s)
        sweep = friction_sweep(axis, driver.sample_period_s, first, gain_nm_per_v, inertia_kg_m2,
                               voltages_per_direction, max_speed_rad_s, pulse_s, travel_rad, progress, cancel)
        volts = next(sweep)
        last_t = first[1]
        while True:
            driver.command(axis, volts)
            driver.tick()
            faults = driver.faults()
            if faults:  # the driver disabled itself: every run after this would read "did not move"
                raise DriverFault(f"friction identification stopped on {axis}: {'; '.join(faults)}")
            t = driver.sample_time_s
            if t == last_t:  # no new reading (an exchange that timed out): the same volts again
                continue
            last_t = t
            volts = sweep.send((driver.read_encoder(axis), t))
    except StopIteration as done:
        result: FrictionResult = done.value
        return result
    finally:
        driver.command(axis, 0.0)
        driver.disable()


def friction_sweep(
    axis: str,
    dt: float,
    first: Reading,
    gain_nm_per_v: float | None = None,
    inertia_kg_m2: float | None = None,
    voltages_per_direction: int = 10,
    max_speed_rad_s: float = 3.0,
    pulse_s: float = SEED_PULSE_S,
    travel_rad: float | None = None,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    *,
    limits_rad: tuple[float, float] | None = None,
    stall_s: float = STALL_S,
) -> Sweep:
    """The experiment of :func:`run_friction_id` as a generator (see ``Sweep``): ``dt`` the
    sample period (s), ``first`` the reading before the first sample; the other arguments as
    there. ``limits_rad``: the lines the positioning moves must never pass, even when the host
    stalls for ``stall_s`` (default: ± the travel). Its return value (``StopIteration.value``)
    is the :class:`FrictionResult`."""
    preset = get_preset(axis)
    gain = preset.gain_nm_per_v if gain_nm_per_v is None else float(gain_nm_per_v)
    inertia = preset.inertia_kg_m2 if inertia_kg_m2 is None else float(inertia_kg_m2)
    travel = preset.soft_limit_rad if travel_rad is None else float(travel_rad)
    end = TRAVEL_FRACTION * travel
    lines = (-travel, travel) if limits_rad is None else (float(limits_rad[0]), float(limits_rad[1]))
    if not (lines[0] < -end and end < lines[1]) or not (math.isfinite(stall_s) and stall_s >= 0):
        raise DataError(f"friction ID on {axis}: the limit lines {lines} must lie beyond the travel "
                        f"±{end:.4f} rad and the stall {stall_s!r} s be >= 0")
    mover = _Mover(gain, inertia, preset.coulomb_nm, lines, float(stall_s))
    ax = _Axis(axis, dt, first, cancel)
    total_runs = 2 * (voltages_per_direction + 1)
    done = 0
    points: list[FrictionPoint] = []
    breakaway: dict[float, float] = {}
    step_rad = 1e-3
    for s in (1.0, -1.0):
        yield from ax.move_to(-s * end, mover)
        v_b = yield from _breakaway_volts(ax, s, 0.4 * preset.coulomb_nm / gain, step_rad)
        breakaway[s] = gain * v_b
        done += 1
        if progress is not None:
            progress(done / total_runs)
        mine: list[FrictionPoint] = []
        speeds = np.linspace(0.1, 1.0, voltages_per_direction) * max_speed_rad_s
        for i in range(voltages_per_direction):
            volts = _next_voltage(mine, s, v_b, speeds[i], gain, i)
            yield from ax.move_to(-s * end, mover)
            target = abs(speeds[i])
            p_len = min(pulse_s, inertia * target / max(gain * SEED_PULSE_V, 1e-9))
            run_s = min(2 * end / max(target, 0.05) + 0.5, MAX_RUN_S)
            run = _constant_voltage_run(ax, s, volts, p_len, s * end, gain, inertia, run_s)
            mine.append((yield from run))
            done += 1
            if progress is not None:
                progress(done / total_runs)
        points += mine
    return FrictionResult(
        axis,
        gain,
        _fit_line(points, 1.0),
        _fit_line(points, -1.0),
        breakaway[1.0],
        breakaway[-1.0],
        tuple(points),
        ax.ticks * ax.dt,
    )


def _next_voltage(
    done: list[FrictionPoint], s: float, v_break: float, speed: float, gain: float, i: int
) -> float:
    """The voltage expected to hold ``speed``.

    With two runs that moved (settled or too fast), from the line through them; before that a
    bracket search: above the highest voltage that stopped, below the lowest that was too fast.
    """
    usable = [p for p in done if p.moved or p.too_fast]
    if len(usable) >= 2:
        w = np.array([abs(p.velocity_rad_s) for p in usable])
        tq = np.array([abs(p.torque_nm) for p in usable])
        if np.ptp(w) > 0:
            slope, icpt = np.polyfit(w, tq, 1)
            if slope > 0:
                return float(max(icpt + slope * speed, 0.0) / gain)
    stuck = [abs(p.volts) for p in done if not (p.moved or p.too_fast)]
    fast = [abs(p.volts) for p in done if p.too_fast]
    lo = max(stuck) if stuck else None
    hi = min(fast) if fast else None
    if hi is not None:
        return 0.5 * ((lo if lo is not None else 0.5 * v_break) + hi)
    if lo is not None:
        return lo * 1.02
    return v_break * (1.0 + 0.01 * (i + 1))


__all__ = ["FrictionLine", "FrictionPoint", "FrictionResult", "Reading", "Sweep", "friction_sweep",
           "run_friction_id"]
