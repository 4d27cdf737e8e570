"""Break-away analysis: the torque at which a stuck axis starts to move, against the model.

At rest the axis holds until the applied torque exceeds the break-away torque (Karnopp). A
model with Coulomb torque Fc predicts motion as soon as ``s·(K·u − τ_other) > Fc_s``. Two
effects raise the observed break-away: static friction above Coulomb (stiction: a constant
excess) and a transport delay (the logged command has risen further by the time the late
torque arrives: an excess ``K·u̇·d`` that grows with the command's rate). Regressing the
excess on [1, K·s·u̇] over all break-away events separates them — slow starts show stiction,
fast ones delay — which one measurement of reversals alone cannot.

The excess of each start is measured directly, as a level: the torque the command applied at
the moment the axis broke away, less the model's Coulomb torque (and its other static
torques). The moment of the break is the encoder's first change less the time the axis needs
to cover that half count after breaking (taken from the model simulated from rest with the
measured command): without it, a slowly rising command on a coarse encoder looks like a delay
and like stiction. (Multiplying a lag by the command's rate instead, as before, assumes a
command that rose at one rate through the lag; in closed loop it seldom does, and a held
command above Coulomb gave no excess at all.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tracker.plant.effects import CATALOGUE, generic_effects
from tracker.plant.model import AxisModel
from tracker.workbench.measurements.data import Measurement

FloatArray = NDArray[np.float64]
MIN_REST_S = 0.05
PRE_S = (0.008, 0.002)  # command averaged over this window before the first count change
MIN_SHARE = 0.5  # the command before a start must reach this share of the Coulomb torque
MAX_JUMP_V = 0.3  # ... and must not have jumped by more than this over the last ~30 ms
# The command may change by at most this share of Coulomb while the axis covers the half count
# after breaking away (or the level read depends on the travel time, which the model only guesses).
MAX_TRAVEL_SWING = 1.0
TRAVEL_ITERATIONS = 2  # the travel after the break measured again with the break-away found
TRAVEL_STRIBECK_RAD_S = 0.05  # Stribeck velocity of that second model (the catalogue's default)
# Starts each way needed, and the t of the difference of their mean excesses beyond which the
# break-away is not symmetric (static friction opposes either way alike; a missing torque of
# position or a bias adds to one direction's break-away what it takes from the other's).
MIN_STARTS_EACH_WAY = 3
MAX_DIRECTION_T = 3.0


@dataclass(frozen=True, slots=True)
class BreakAway:
    """Break-away events and the fit excess = a + d·(K·s·u̇).

    ``excess_nm`` (shape (m,)) is the observed break-away torque minus the model's;
    ``rate_nm_s`` the torque rate K·s·u̇ at each; ``static_excess_nm`` (a) and ``delay_s`` (d)
    with standard errors; ``coulomb_nm`` the model's Coulomb torque (positive direction) the
    excess is measured over.
    """

    count: int
    excess_nm: FloatArray
    rate_nm_s: FloatArray
    static_excess_nm: float
    static_excess_se: float
    delay_s: float
    delay_se: float
    coulomb_nm: float = 0.0
    direction: FloatArray = field(default_factory=lambda: np.zeros(0))  # each start's way (+1, -1), (m,)

    def direction_difference(self) -> tuple[float, float] | None:
        """(mean excess of the starts in the positive direction − that of the negative ones, its
        standard error; N·m), or None with fewer than ``MIN_STARTS_EACH_WAY`` starts either way."""
        parts = [self.excess_nm[self.direction == s] for s in (1.0, -1.0)]
        if self.direction.size != self.excess_nm.size or min(p.size for p in parts) < MIN_STARTS_EACH_WAY:
            return None
        se = math.sqrt(sum(float(np.var(p, ddof=1)) / p.size for p in parts))
        return float(parts[0].mean() - parts[1].mean()), se

    def one_sided(self) -> str | None:
        """Why the excess is not static friction's alone, or None: the starts of the two directions
        break away at excesses that differ beyond ``MAX_DIRECTION_T`` standard errors (the axis is
        held by a torque the model lacks, gravity or a bias, against one direction more)."""
        diff = self.direction_difference()
        if diff is None or not diff[1] > 0 or abs(diff[0]) <= MAX_DIRECTION_T * diff[1]:
            return None
        return (
            f"the starts break away {1e3 * abs(diff[0]):.3g} ± {1e3 * diff[1]:.2g} mN·m later "
            f"{'positive' if diff[0] > 0 else 'negative'} than the other way: a torque the model "
            "lacks holds the axis one way, which static friction (the same both ways) does not"
        )

    @property
    def static_t(self) -> float:
        return self.static_excess_nm / self.static_excess_se if self.static_excess_se > 0 else 0.0


def other_torque(model: AxisModel, theta: FloatArray) -> FloatArray:
    """Direction-independent static torques (offset, gravity, ripple, generic effects) at θ."""
    out = np.zeros_like(theta)
    for e in ("offset", "gravity", "ripple", *generic_effects()):
        if model.has(e):
            out += CATALOGUE[e].torque_nm(model.params, theta, np.zeros_like(theta))
    return out


def coulomb_around_sliding(model: AxisModel, sliding_coulomb_nm: float) -> tuple[float, float]:
    """The model's Coulomb torques (positive, negative direction; N·m) moved so that their mean
    is the sliding Coulomb the regression measured on moving data (the model's own may have
    absorbed part of a missing break-away); a direction-dependent split is kept around it."""
    p = model.params
    fc_pos = float(p["coulomb.torque"])
    fc_neg = float(p["coulomb_asymmetry.negative"]) if model.has("coulomb_asymmetry") else fc_pos
    shift = sliding_coulomb_nm - 0.5 * (fc_pos + fc_neg)
    return fc_pos + shift, fc_neg + shift


def _first_crossing(theta: FloatArray, start: float, direction: float, distance: float) -> float:
    """Fractional sample where ``direction·(θ − start)`` first reaches ``distance``; inf if never."""
    d = direction * (theta - start)
    hit = np.flatnonzero(d >= distance)
    if hit.size == 0:
        return math.inf
    i = int(hit[0])
    if i == 0:
        return 0.0
    return float(i - 1 + (distance - d[i - 1]) / max(d[i] - d[i - 1], 1e-300))


def analyse_breakaway(meas: Measurement, model: AxisModel) -> BreakAway | None:
    """Find creeping starts from rest in ``meas`` and fit their excess over ``model``; None if < 4.

    For each start the model is simulated from rest with the measured command, and the time its
    angle first moves half an encoder count is set against the time the encoder first changed:
    the time a real axis needs to cover that half count after breaking away is then in both
    (without it, a slowly rising command looks like a delay and like stiction). The lag, times
    the torque's rate, is the excess break-away torque of that start.
    """
    th, u, dt = meas.theta_rad, meas.u_v, meas.dt_s
    change = np.flatnonzero(np.diff(th) != 0.0) + 1
    if change.size < 2:
        return None
    gaps = np.diff(change)
    min_rest = int(round(MIN_REST_S / dt))
    rest_len = gaps[gaps >= min_rest]
    ends = change[1:][gaps >= min_rest]  # first sample that moved after a long rest
    pre0, pre1 = int(round(PRE_S[0] / dt)), max(1, int(round(PRE_S[1] / dt)))
    slope_n = max(3, int(round(0.02 / dt)))
    after = int(round(0.03 / dt))
    k_gain = model.gain_nm_per_v
    p = model.params
    fc_pos = p["coulomb.torque"]
    fc_neg = p.get("coulomb_asymmetry.negative", fc_pos) if model.has("coulomb_asymmetry") else fc_pos
    if model.has("stiction"):
        fc_pos = max(fc_pos, p["stiction.static_torque"])
        fc_neg = max(fc_neg, p["stiction.static_torque"])
    steps = np.abs(np.diff(th))
    steps = steps[steps > 0]
    count = float(np.min(steps)) if steps.size else 0.0
    ex, rate, way = [], [], []
    for e, gap in zip(ends, rest_len, strict=True):
        if e - slope_n - pre0 < 0 or e + after >= th.size:
            continue
        s = math.copysign(1.0, th[e + after] - th[e - 1])
        if th[e + after] == th[e - 1]:
            continue
        u_b = float(np.mean(u[e - pre0 : e - pre1]))
        tt = np.arange(slope_n) * dt
        du = float(np.polyfit(tt, u[e - pre1 - slope_n : e - pre1], 1)[0])
        # Only starts where the command crept up to the threshold say what the threshold is
        # (after a command step the axis starts at once, whatever its break-away torque).
        early = float(np.mean(u[e - pre0 - slope_n : e - pre1 - slope_n]))
        jump = abs(u_b - early)
        if s * k_gain * u_b < MIN_SHARE * min(fc_pos, fc_neg) or jump > MAX_JUMP_V or s * du <= 0:
            continue
        fc_s = fc_pos if s > 0 else fc_neg
        held = _break_torque_nm(meas, model, int(e), int(min(gap, e)), s, 0.5 * count)
        if not math.isfinite(held):
            continue
        ex.append(held - fc_s)
        rate.append(k_gain * s * du)
        way.append(s)
    if len(ex) < 4:
        return None
    y, r = np.array(ex), np.array(rate)
    x = np.column_stack([np.ones_like(r), r])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    res = y - x @ coef
    sigma2 = float(res @ res) / max(1, y.size - 2)
    try:
        cov = np.linalg.inv(x.T @ x) * sigma2
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        se = np.array([math.inf, math.inf])
    return BreakAway(
        y.size, y, r, float(coef[0]), float(se[0]), float(coef[1]), float(se[1]), float(fc_pos), np.array(way)
    )


def _broke_at_a_step(u: FloatArray, at: int) -> bool:
    """Whether the command the axis received at its break, ``u[at]``, sits on a plateau the
    command stepped onto by more than ``MAX_JUMP_V``.

    Static friction gives way only while the torque changes: an axis held at rest under a torque
    stays held while that torque is constant. A break placed on a plateau (the command constant
    over that sample and a neighbour) therefore happened where the plateau began, give or take
    the travel's guess (where in its count the axis sat); there the torque went from the value
    before the step, which the axis held, to the plateau's, which it did not, and the break-away
    lies somewhere between the two. After a small step (a staircase, a quantized command) that
    is a level; after a step larger than a creeping start may jump, it says only that the
    break-away is below the plateau. A voltage step behind a drive delay breaks away at the
    step's level a fixed time after the step: read as a level, every such start measured the
    step's height over Coulomb (a delay-only step log's second round: +0.094 ± 0.025 N·m in 28
    starts, whose command was flat to rounding through the 20 ms the creep test looks at).
    A closed-loop command changes at every sample and is never on a plateau."""
    n = u.size
    on_plateau = (at > 0 and u[at - 1] == u[at]) or (at + 1 < n and u[at + 1] == u[at])
    if not on_plateau:
        return False
    p0 = at
    while p0 > 0 and u[p0 - 1] == u[at]:
        p0 -= 1
    return p0 == 0 or abs(float(u[p0] - u[p0 - 1])) > MAX_JUMP_V


def _break_torque_nm(
    meas: Measurement, model: AxisModel, first_moved: int, rest: int, direction: float, distance: float
) -> float:
    """The torque ``s·(K·u − τ_other)`` the axis held when it broke away after a rest; nan if unknown.

    The model starts at rest ``rest`` samples before ``first_moved`` (at most 0.5 s) at the held
    angle, driven by the measured command; the samples it needs from its last moment at rest to
    its first crossing of ``distance`` (half a count) are the axis's travel time. The real break is
    that long before the encoder's change (taken half a sample before ``first_moved``, the
    middle of the period in which the count changed); the command applied then (the model's
    delay, if it has one, accounted for) is the break-away torque. An axis breaking away above
    Coulomb covers the half count sooner than the model, so the travel is measured again with
    the model given that break-away (``TRAVEL_ITERATIONS``). A start whose command swept by more
    than ``MAX_TRAVEL_SWING`` of Coulomb through the travel says nothing (nan): its level would
    be the travel time's guess (a fast chirp on a coarse encoder).
    """
    from tracker.plant.simulate import initial_state, simulate

    dt = meas.dt_s
    lead = min(rest, int(round(0.5 / dt)))
    k0 = first_moved - lead
    k1 = min(meas.n, first_moved + int(round(0.2 / dt)))
    rigid = model
    for effect in ("backlash", "compliance"):
        if rigid.has(effect):
            rigid = rigid.without_effect(effect)
    theta0 = float(meas.theta_rad[first_moved - 1])
    other = float(other_torque(model, np.array([theta0]))[0])
    delay = model.params.get("delay.seconds", 0.0) / dt if model.has("delay") else 0.0
    level = math.nan
    for _ in range(TRAVEL_ITERATIONS):
        run = simulate(rigid, meas.u_v[k0:k1], dt, x0=initial_state(theta0), quantize=False)
        sim_k = _first_crossing(run.theta_rad, theta0, direction, distance)
        if not math.isfinite(sim_k):
            return level
        # The model's last moment at rest before it crossed (it may stick and slip on the way).
        held = np.flatnonzero(run.omega_rad_s[: int(math.ceil(sim_k)) + 1] == 0.0)
        if held.size == 0:
            return level  # the model never held: nothing says when it broke away
        travel = sim_k - float(held[-1])
        at = int(math.floor(k0 + (lead - 0.5) - travel - delay))
        if at < 0 or at >= first_moved:
            return level
        if _broke_at_a_step(meas.u_v, at):
            return math.nan  # the axis broke at a step to this level: its break-away is below it
        level = direction * (model.gain_nm_per_v * float(meas.u_v[at]) - other)
        swing = model.gain_nm_per_v * float(np.ptp(meas.u_v[at:first_moved]))
        if swing > MAX_TRAVEL_SWING * float(model.params["coulomb.torque"]):
            return math.nan  # the command swept through the travel: its level is the travel's guess
        # An axis that breaks away at that level starts with the excess over Coulomb and covers
        # the half count sooner than the model's: measure its travel again with it.
        fc = float(model.params["coulomb.torque"])
        if level <= fc:
            return level
        effects = rigid.effects if rigid.has("stiction") else (*rigid.effects, "stiction")
        values = {"stiction.static_torque": level, "stiction.velocity": TRAVEL_STRIBECK_RAD_S}
        rigid = AxisModel.create(rigid.gain_nm_per_v, {}, effects, {**rigid.params, **values})
    return level


__all__ = ["BreakAway", "analyse_breakaway"]
