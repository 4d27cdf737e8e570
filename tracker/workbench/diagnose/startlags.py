"""Start lags from rest: a constant lag (a drive delay) against a break-away level (stiction).

Stiction and a delay both make an axis start late from rest, and both raise the torque the
command shows when it starts. What differs is *when*: a delay makes every start late by the
same time after the torque crossed the level the model needs to move (Coulomb), whatever the
command did meanwhile; static friction holds until the torque reaches the break-away level,
so the lag is long when the torque creeps past Coulomb and short after a step past it.

For each start from rest (no encoder change for ``MIN_REST_S``, then a change), with
``τ = s·(K·u − τ_other)`` the torque applied in the direction ``s`` of the start, ``k`` the
first sample of the last stretch in which τ stayed at or above the sliding Coulomb torque, and
``e`` the sample at which the encoder changed, the start's time is ``(e − k)·dt``. Each story
predicts it:

* a delay ``d``:      ``d + T(τ)``   (``T``: the rigid model's time to reach the next count),
* a break-away ``F``: ``t_F + T(F)`` (``t_F``: the time τ took to reach ``F`` after ``k``).

The scatter each start is allowed comes from the log, not from the fit: the axis sits anywhere
within its count, so the time to the next count is spread over ``[0, T]`` (``T·√U``, U
uniform: standard deviation ``T/√18``, mean ``2T/3``); a sample period's rounding
(``dt/√12``); and the disturbance, a torque the model does not know, which moves the break by
its standard deviation (the slow residual torque) over the torque's rate. "Neither" allows a
lag of up to ``MIN_DELAY_SAMPLES`` (the loop's own timing). Each story's one parameter is
fitted by weighted least squares, and the stories are compared by their χ² (same number of
parameters), scaled by the best story's χ² per degree of freedom when the log scatters more
than that: a difference beyond ``MIN_CHI2`` says which explains the start times, both ways —
a constant lag opens the delay's refit by simulation, a lag that follows a level past the
Stribeck dip opens stiction's and keeps the delay's grid gain from passing.
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
from tracker.workbench.measurements.idim import Signals

FloatArray = NDArray[np.float64]
MIN_REST_S = 0.05  # a rest: no encoder change for at least this long (as the break-away analysis)
MIN_STARTS = 6  # starts needed to judge
# χ² difference that decides between two one-parameter stories (likelihood ratio e^(Δ/2) ≈
# 1000), and of either story against none (the same, as a 1-dof χ² at p ≈ 5·10⁻⁴).
MIN_CHI2 = float(stats.chi2.ppf(1.0 - 5e-4, 1))
# A constant lag shorter than this is the loop's own timing (a computational latency of one
# sample, seen up to a sample later by when in the period the encoder is read), not a drive's.
MIN_DELAY_SAMPLES = 2.0
# Break-away levels tried: steps of 1 % of Coulomb up to 3 × it (or the highest start torque).
LEVEL_STEP = 0.01
LEVEL_GRID = 300
MAX_LAG_S = 0.2  # starts whose torque stayed above Coulomb longer than this are not timed


@dataclass(frozen=True, slots=True)
class StartLags:
    """What the start times from rest say.

    ``count`` starts timed; ``delay_s`` the constant lag that fits them best and ``level_nm``
    the break-away level that fits best; ``chi2_none``, ``chi2_delay``, ``chi2_level`` each
    story's weighted squared misfit (no delay and no break-away above Coulomb, a delay, a
    break-away level).
    """

    count: int
    delay_s: float
    level_nm: float
    coulomb_nm: float
    chi2_none: float
    chi2_delay: float
    chi2_level: float
    dt_s: float
    # The break-away levels tried (absolute, N·m) and each one's χ² (empty when none was tried).
    levels_nm: tuple[float, ...] = ()
    chi2_levels: tuple[float, ...] = ()

    def _scale(self, chi2: float) -> float:
        """The log's own scatter: the best story's χ² per degree of freedom, at least 1 (the
        scatter the encoder and the sampling allow; a disturbance or a rough model adds more)."""
        return max(chi2 / max(self.count - 1, 1), 1.0)

    def favours_delay(self) -> bool:
        """A constant lag of at least ``MIN_DELAY_SAMPLES`` explains the starts, significantly
        better (on the log's own scatter) than none and than a break-away level."""
        scale = self._scale(self.chi2_delay)
        return (
            self.delay_s >= MIN_DELAY_SAMPLES * self.dt_s
            and (self.chi2_none - self.chi2_delay) / scale > MIN_CHI2
            and (self.chi2_level - self.chi2_delay) / scale > MIN_CHI2
        )

    def favours_level(self) -> bool:
        """A break-away level past a Stribeck dip explains the starts, significantly better (on
        the log's own scatter) than none and than a constant lag.

        A level within ``stiction.ESTABLISHED_EXCESS_RATIO`` of the sliding Coulomb torque is
        that torque misestimated (or a Stribeck dip), not static friction.
        """
        scale = self._scale(self.chi2_level)
        return (
            self.level_nm > (1.0 + stiction_effect.ESTABLISHED_EXCESS_RATIO) * self.coulomb_nm
            and (self.chi2_none - self.chi2_level) / scale > MIN_CHI2
            and (self.chi2_delay - self.chi2_level) / scale > MIN_CHI2
        )

    def rejects_level(self, level_nm: float) -> bool:
        """Whether the start times reject a break-away at ``level_nm`` (a level fitted some other
        way, by simulation): its χ² exceeds the best level's by more than ``MIN_CHI2`` on the
        log's own scatter. A level at or under Coulomb is the "neither" story; one above every
        level tried is judged at the highest tried (the torque reached it on some start). Starts
        a constant lag explains significantly better than any level measure no break-away, and
        reject none."""
        if (
            not self.levels_nm
            or (self.chi2_level - self.chi2_delay) / self._scale(self.chi2_delay) > MIN_CHI2
        ):
            return False
        scale = self._scale(self.chi2_level)
        if level_nm <= self.coulomb_nm:
            chi2 = self.chi2_none
        else:
            i = int(np.searchsorted(np.asarray(self.levels_nm), level_nm))
            chi2 = self.chi2_levels[min(i, len(self.chi2_levels) - 1)]
        return (chi2 - self.chi2_level) / scale > MIN_CHI2

    def describe(self) -> str:
        return (
            f"{self.count} starts from rest: a constant lag of {1e3 * self.delay_s:.1f} ms after the "
            f"torque crossed Coulomb gives χ² {self.chi2_delay:.0f}, a break-away at "
            f"{self.level_nm:.3g} N·m (Coulomb {self.coulomb_nm:.3g}) {self.chi2_level:.0f}, "
            f"neither {self.chi2_none:.0f}"
        )


def _travel_times_s(excess_nm: FloatArray, j: float, b: float, count_rad: float) -> FloatArray:
    """:func:`tracker.workbench.diagnose.rests._travel_time_s` over an array of net torques
    (inf where not positive): the time a rigid axis from rest needs to cover ``count_rad``."""
    f = np.asarray(excess_nm, dtype=float)
    out = np.full(f.shape, math.inf)
    pos = f > 0
    if not pos.any():
        return out
    fp = f[pos]
    rigid = np.sqrt(2.0 * count_rad * j / fp)
    if b <= 0:
        out[pos] = rigid
        return out
    tau = j / b

    def covered(t: FloatArray) -> FloatArray:
        return np.asarray((fp / b) * (t - tau * (-np.expm1(-t / tau))), dtype=float)

    lo, hi = np.zeros_like(fp), np.maximum(rigid, 1e-9)
    for _ in range(60):  # the viscous drag only lengthens it: double until the count is covered
        short = covered(hi) < count_rad
        if not short.any():
            break
        hi = np.where(short, 2.0 * hi, hi)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        below = covered(mid) < count_rad
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    out[pos] = hi
    return out


@dataclass(frozen=True, slots=True)
class _Start:
    torque: FloatArray  # τ from the crossing k to the sample before the change
    elapsed_s: float  # (e − k)·dt


def _starts(
    torque: FloatArray, theta: FloatArray, fc: tuple[float, float], dt: float
) -> list[tuple[_Start, float]]:
    change = np.flatnonzero(np.diff(theta) != 0.0) + 1
    if change.size < 2:
        return []
    gaps = np.diff(change)
    min_rest = int(math.ceil(MIN_REST_S / dt))
    out = []
    for e, gap in zip(change[1:], gaps, strict=True):
        if gap < min_rest:
            continue
        a = int(e - gap)
        s = math.copysign(1.0, float(theta[e] - theta[e - 1]))
        f = fc[0] if s > 0 else fc[1]
        tq = s * torque[a:e]
        below = np.flatnonzero(tq < f)
        if below.size == 0 or below[-1] == tq.size - 1:
            continue  # above Coulomb all the rest (no crossing to time from), or started below it
        k = int(below[-1]) + 1
        if (tq.size - k) * dt > MAX_LAG_S:
            continue
        out.append((_Start(tq[k:], (tq.size - k) * dt), f))
    return out


def analyse_start_lags(
    sig: Signals, model: AxisModel, sliding_coulomb_nm: float, disturbance_nm: float = 0.0
) -> StartLags | None:
    """Time every start from rest against ``model`` (rigid, no stiction; its delay, if any, applied) and
    ``sliding_coulomb_nm`` (the torque regression's Coulomb); None with too few starts.

    ``disturbance_nm``: the standard deviation of the torque the model does not know on a
    rest's time scale (:func:`tracker.workbench.diagnose.rests.slow_residual_nm`); it moves the
    moment the axis breaks away by itself over the torque's rate, which each start is allowed.
    """
    theta, dt, count = sig.theta_raw_rad, sig.dt_s, sig.encoder_step_rad
    if count <= 0 or sliding_coulomb_nm <= 0:
        return None
    p = model.params
    fc = coulomb_around_sliding(model, sliding_coulomb_nm)
    j, b = float(p["inertia.J"]), float(p["viscous.b"])
    torque = model.gain_nm_per_v * sig.u_v - other_torque(model, theta)
    if model.has("delay"):
        # The torque as it reaches the axis: the lag left is what the model's delay misses.
        lag = int(round(float(p["delay.seconds"]) / dt))
        if lag > 0:
            torque = np.concatenate([np.full(lag, torque[0]), torque[:-lag]])
    starts = _starts(torque, theta, fc, dt)
    if len(starts) < MIN_STARTS:
        return None
    elapsed = np.array([st.elapsed_s for st, _ in starts])
    # The travel to the next count at the torque applied (its mean over the lag), and the
    # scatter the unknown place within the count and the sampling allow each start.
    travel = _travel_times_s(np.array([float(np.mean(st.torque)) - f for st, f in starts]), j, b, count)
    travel = np.minimum(travel, MAX_LAG_S)
    # The torque's rate over the lag (a step: its rise over the lag, a large rate).
    rate = np.array([max(float(st.torque[-1]) - f, 0.0) for st, f in starts]) / np.maximum(elapsed, dt)
    timing = np.where(rate > 0, disturbance_nm / np.maximum(rate, 1e-300), MAX_LAG_S)
    var = travel**2 / 18.0 + dt**2 / 12.0 + np.minimum(timing, MAX_LAG_S) ** 2
    w = 1.0 / var
    mean_travel = 2.0 / 3.0 * travel
    # Delay: elapsed = d + 2T/3 (weighted least squares, d >= 0).
    d = max(float(np.sum(w * (elapsed - mean_travel)) / np.sum(w)), 0.0)
    # "None": no lag beyond the loop's own timing (up to MIN_DELAY_SAMPLES: a sample of
    # computational latency, and where in the period the count changed).
    d_none = min(d, MIN_DELAY_SAMPLES * dt)
    chi2_none = float(np.sum(w * (elapsed - d_none - mean_travel) ** 2))
    chi2_delay = float(np.sum(w * (elapsed - d - mean_travel) ** 2))
    # Break-away level F: elapsed = t_F + 2T(F)/3 (a grid from Coulomb to the highest torque).
    top = max(float(np.max(st.torque)) - f for st, f in starts)
    grid = np.arange(1, LEVEL_GRID + 1) * sliding_coulomb_nm * LEVEL_STEP
    grid = grid[grid < top]
    best_level, chi2_level = 0.0, chi2_none
    chi2 = np.zeros(0)
    if grid.size:
        reach_s = np.full((grid.size, len(starts)), math.inf)
        excess_after = np.zeros((grid.size, len(starts)))
        for i, (st, f) in enumerate(starts):
            # First sample at or above each level (the running maximum is non-decreasing), and
            # the mean torque from there to the start.
            first = np.searchsorted(np.maximum.accumulate(st.torque), f + grid, side="left")
            ok = first < st.torque.size
            csum = np.concatenate([[0.0], np.cumsum(st.torque)])
            reach_s[ok, i] = first[ok] * dt
            excess_after[ok, i] = (csum[-1] - csum[first[ok]]) / (st.torque.size - first[ok]) - f
        t_travel = np.minimum(_travel_times_s(excess_after, j, b, count), MAX_LAG_S)
        pred = reach_s + 2.0 / 3.0 * t_travel
        # A level the torque never reached, yet the axis moved: the largest misfit allowed.
        resid = np.where(np.isfinite(pred), elapsed[None, :] - pred, MAX_LAG_S)
        chi2 = np.sum(w[None, :] * resid**2, axis=1)
        i_best = int(np.argmin(chi2))
        if chi2[i_best] < chi2_level:
            best_level, chi2_level = float(grid[i_best]), float(chi2[i_best])
    return StartLags(
        len(starts),
        d,
        sliding_coulomb_nm + best_level,
        sliding_coulomb_nm,
        chi2_none,
        chi2_delay,
        chi2_level,
        dt,
        tuple(float(v) for v in sliding_coulomb_nm + grid[: chi2.size]),
        tuple(float(v) for v in chi2),
    )


__all__ = ["MIN_CHI2", "StartLags", "analyse_start_lags"]
