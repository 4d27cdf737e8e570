"""Rests that held: torque beyond Coulomb applied long enough to move, and the encoder still.

A command that creeps up to the break-away shows static friction where the axis starts
(:mod:`tracker.workbench.diagnose.breakaway`). A command that *steps* (open-loop voltage steps)
gives no creeping start: the axis starts at once after a step past the break-away torque, and
after a step to a level between the Coulomb and the break-away torque it never starts. That
rest is the evidence: the model without stiction, holding that torque, moves a count; the axis
does not.

For each rest (no encoder change for at least ``MIN_REST_S``) and each direction, the *held
torque* is the highest level the applied torque ``s·(K·u − τ_other)`` kept for a stretch long
enough that the model — friction at Coulomb plus the margin — would cover a whole encoder count
in it, plus the lag of the log's own prompt starts (so a drive delay, which makes every start
late by the same time, is not taken for an axis that held). The margin is the log's own: a
share of Coulomb well past a Stribeck dip (``stiction.ESTABLISHED_EXCESS_RATIO``) plus ``Z_DISTURBANCE``
standard deviations of the slow residual torque (the disturbance and the model's errors on the
time scale of a rest) and of the Coulomb estimate. A clean axis holds beyond that margin only
when the disturbance pushes back by more than ``Z_DISTURBANCE`` of its own standard deviations:
a rest with probability at most Φ(−Z) under the null, so ``k`` such rests of ``m`` give a
binomial tail probability that judges the evidence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from tracker.plant.effects import stiction as stiction_effect
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.breakaway import coulomb_around_sliding, other_torque
from tracker.workbench.measurements.idim import Regression, Signals

FloatArray = NDArray[np.float64]
MIN_REST_S = 0.05  # a rest: no encoder change for at least this long (as the break-away analysis)
SLOW_S = 0.05  # the residual torque averaged over blocks this long: the disturbance a rest sees
Z_DISTURBANCE = 3.0  # standard deviations of slow residual torque (and Coulomb estimate) in the margin
MAX_HOLD_P = 1e-3  # binomial tail probability under which rests that held establish stiction
LEVELS = 24  # torque levels tried per rest (quantiles of the torque applied in it)


@dataclass(frozen=True, slots=True)
class RestHolds:
    """What the rests of a log say about static friction.

    ``rests`` rests were long enough to judge; ``held`` of them held a torque beyond
    ``coulomb_nm + margin_nm`` long enough for the model to move a count; ``held_nm`` are those
    torque levels (shape (held,)); ``p_value`` the binomial tail of ``held`` out of ``rests`` with
    per-rest chance ``Φ(−Z_DISTURBANCE)``; ``start_lag_s`` the lag of prompt starts allowed for;
    ``both_ways`` whether rests held against torques of both signs (static friction opposes either
    way; a missing bias or gravity torque, absent from the model, holds the axis only against
    itself).
    """

    rests: int
    held: int
    held_nm: FloatArray
    coulomb_nm: float
    margin_nm: float
    disturbance_nm: float
    start_lag_s: float
    p_value: float
    both_ways: bool = True  # rests held against a torque of either sign

    @property
    def level_nm(self) -> float:
        """A lower bound of the break-away torque: the median torque the rests that held held."""
        return float(np.median(self.held_nm)) if self.held_nm.size else math.nan

    def established(self) -> str | None:
        """Evidence that static friction is established by the rests alone, or None."""
        if self.held < 2 or self.p_value > MAX_HOLD_P or not self.both_ways:
            return None
        fc = self.coulomb_nm
        return (
            f"{self.held} of {self.rests} rests held a torque beyond Coulomb and the disturbance "
            f"margin (Coulomb {fc:.3g} N·m + {self.margin_nm:.2g}) long enough for the model to "
            f"move a count, and the encoder did not change (median held {self.level_nm:.3g} N·m, "
            f"{100 * (self.level_nm - fc) / fc:.0f} % above Coulomb; chance {self.p_value:.1g}): "
            "static friction"
        )


def slow_residual_nm(sig: Signals, reg: Regression) -> float:
    """Standard deviation of the residual torque averaged over ``SLOW_S`` blocks of moving data.

    The sample-rate residual is dominated by the encoder's differentiated quantization, which
    averages out; what remains on a rest's time scale is the disturbance and the model's error.
    """
    if reg.residual.size < 2:
        return 0.0
    block = np.floor(sig.use * sig.dt_s / SLOW_S).astype(np.int64)
    _, inv, counts = np.unique(block, return_inverse=True, return_counts=True)
    sums = np.bincount(inv, weights=reg.residual)
    means = sums[counts >= 3] / counts[counts >= 3]
    return float(np.std(means)) if means.size >= 3 else float(np.std(reg.residual))


def _travel_time_s(excess_nm: float, j: float, b: float, count_rad: float) -> float:
    """Time a rigid axis from rest needs to cover ``count_rad`` under net torque ``excess_nm``
    (inertia ``j``, viscous ``b``): θ(t) = (F/b)·(t − (1 − e^(−b·t/J))·J/b)."""
    if excess_nm <= 0:
        return math.inf
    if b <= 0:
        return math.sqrt(2.0 * count_rad * j / excess_nm)
    if count_rad * b * b / (excess_nm * j) < 1e-6:  # viscous negligible over that travel
        return math.sqrt(2.0 * count_rad * j / excess_nm)
    tau = j / b
    lo, hi = 0.0, max(math.sqrt(2.0 * count_rad * j / excess_nm), 1e-9)
    while (excess_nm / b) * (hi - tau * (1.0 - math.exp(-hi / tau))) < count_rad:
        hi *= 2.0
        if hi > 1e6:
            return math.inf
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if (excess_nm / b) * (mid - tau * (1.0 - math.exp(-mid / tau))) < count_rad:
            lo = mid
        else:
            hi = mid
    return hi


def _longest_run(mask: NDArray[np.bool_]) -> int:
    if not mask.any():
        return 0
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return int(np.max(np.flatnonzero(d == -1) - np.flatnonzero(d == 1)))


def _rests(theta: FloatArray, dt: float) -> list[tuple[int, int]]:
    """[a, b) stretches with no encoder change, at least ``MIN_REST_S`` long (b: first change)."""
    change = np.flatnonzero(np.diff(theta) != 0.0) + 1
    bounds = np.concatenate([[0], change, [theta.size]])
    min_len = int(math.ceil(MIN_REST_S / dt))
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b - a >= min_len]


def _start_lags_s(
    torque: FloatArray,
    rests: list[tuple[int, int]],
    n: int,
    fc: tuple[float, float],
    threshold: float,
    j: float,
    b: float,
    count: float,
    dt: float,
) -> list[float]:
    """Lags of starts that follow a step of the torque past Coulomb + margin: the time from the
    step to the encoder's change, less the model's time to cover a count at that torque."""
    lags = []
    for a, end in rests:
        if end >= n:
            continue
        for s, f in ((1.0, fc[0]), (-1.0, fc[1])):
            tq = s * torque[a:end]
            level = float(tq[-1])
            if level < f + threshold:
                continue
            below = np.flatnonzero(tq < f + threshold)
            if below.size == 0:
                continue  # beyond the threshold the whole rest: no step to time it from
            step = int(below[-1]) + 1  # first sample of the last stretch beyond it
            # ... or of the last step up within that stretch (a stair's last step)
            jumps = np.flatnonzero(np.diff(tq[step:]) >= 0.5 * threshold)
            if jumps.size:
                step += int(jumps[-1]) + 1
            lags.append((tq.size - step) * dt - _travel_time_s(level - f, j, b, count))
    return lags


def analyse_rests(
    sig: Signals, reg: Regression, model: AxisModel, sliding_coulomb_nm: float
) -> RestHolds | None:
    """The rests of the run against ``model`` without stiction; None when the encoder never moves.

    ``sliding_coulomb_nm`` is the Coulomb torque the moving data give (the torque regression:
    the model's own may have absorbed part of a missing break-away); a direction-dependent
    Coulomb of the model keeps its split around it.
    """
    theta, u, dt = sig.theta_raw_rad, sig.u_v, sig.dt_s
    count = sig.encoder_step_rad
    if count <= 0 or sliding_coulomb_nm <= 0:
        return None
    p = model.params
    fc = coulomb_around_sliding(model, sliding_coulomb_nm)
    j = float(p["inertia.J"])
    b = float(p["viscous.b"])
    coulomb_se = 0.0
    if "coulomb.torque" in reg.names:
        i = reg.names.index("coulomb.torque")
        coulomb_se = float(math.sqrt(max(reg.cov[i, i], 0.0)))
    disturbance = slow_residual_nm(sig, reg)
    margin = stiction_effect.ESTABLISHED_EXCESS_RATIO * sliding_coulomb_nm + Z_DISTURBANCE * math.hypot(
        disturbance, coulomb_se
    )
    torque = model.gain_nm_per_v * u - other_torque(model, theta)
    if model.has("delay"):
        lag = int(round(p["delay.seconds"] / dt))
        if lag > 0:
            torque = np.concatenate([np.full(lag, torque[0]), torque[:-lag]])
    rests = _rests(theta, dt)
    if not rests:
        return None
    lags = _start_lags_s(torque, rests, theta.size, fc, margin, j, b, count, dt)
    # A drive delay makes every start late by the same time: allow the longest lag of the log's
    # starts (a sample when there are none) before a held torque counts. Static friction starts
    # at once after a step past the break-away and never while the torque holds below it.
    start_lag = max(max(lags) if lags else 0.0, 0.0) + dt
    held: list[float] = []
    directions: set[float] = set()
    for a, end in rests:
        best, side = -math.inf, 0.0
        for s, f in ((1.0, fc[0]), (-1.0, fc[1])):
            tq = s * torque[a:end]
            if end < theta.size:
                tq = tq[:-1]  # the sample the encoder changed at belongs to the start
            top = float(np.max(tq)) if tq.size else -math.inf
            if top < f + margin:
                continue
            for level in np.unique(np.quantile(tq[tq >= f + margin], np.linspace(0.0, 1.0, LEVELS))):
                need = _travel_time_s(float(level) - f - margin, j, b, count) + start_lag
                if _longest_run(tq >= level) * dt >= need and level > best:
                    best, side = float(level), s
        if math.isfinite(best):
            held.append(best)
            directions.add(side)
    m = len(rests)
    p0 = float(stats.norm.sf(Z_DISTURBANCE))
    p_value = float(stats.binom.sf(len(held) - 1, m, p0)) if held else 1.0
    return RestHolds(
        m,
        len(held),
        np.array(held, dtype=float),
        sliding_coulomb_nm,
        margin,
        disturbance,
        start_lag,
        p_value,
        len(directions) == 2,
    )


__all__ = ["RestHolds", "analyse_rests", "slow_residual_nm"]
