"""What only the windows of steady sliding tell: a drive delay and a belt act in every regime.

Friction's pre-sliding (LuGre's bristles) is a lag and a spring to the frame that act only at
rest and for a short travel after a reversal; a drive delay lags the whole input and a belt
couples motor and load whatever the axis does. So a delay or a belt the whole run favours must
also win in the k-step windows where the axis slides one way throughout
(:meth:`KStepJudge.sliding`). The bars of the judgement are passed in (``min_gain``: the k-step
margin; ``large_gain``: a share of the error removed that needs no t-test).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.kstep import KStepJudge, KStepScore, refine, with_values

FloatArray = NDArray[np.float64]

MIN_SLIDING_WINDOWS = 20  # windows of steady sliding needed to tell a delay from pre-sliding lag
# What the rigid body refits there, with and without the delay (see lags_while_sliding).
SLIDING_REFIT = ("inertia.J", "viscous.b", "coulomb.torque")
SLIDING_REFIT_EVALS = 30
# ... a delay traded the inertia when the rigid body refitted without it takes this many times the
# delay model's inertia there (gen2 seed 7 clean-029: 3.2x; true delays of truthgen: about 1x).
TRADED_INERTIA_RATIO = 2.0
# A belt acts in every regime, friction's pre-sliding spring only at rest and after reversals: a
# belt must also predict better in the windows of steady sliding, by a paired t over their
# blocks of at least this (:func:`resonates_while_sliding`).
MIN_SLIDING_BELT_T = 2.0


def lags_while_sliding(judge: KStepJudge, model: AxisModel, score: KStepScore, min_gain: float) -> bool:
    """Whether a delay beyond one sample also shows where the axis slides steadily.

    A drive delay lags the whole input, so it predicts better wherever the command changes,
    also in windows where the axis slides one way throughout. Friction's pre-sliding (LuGre's
    bristles) lags the response only at rest and after reversals, where it looks like a delay
    of a couple of samples: the delay beyond one sample (a computational latency, reported
    apart) must cut the error of those windows by the k-step margin (``min_gain``). Runs with too little
    steady sliding to tell keep the judgement of the whole run.

    The delay is also set against the best the rigid body does without it there: the model
    without its delay and the model with it, each with its inertia, viscous and Coulomb
    friction refitted by simulation on those windows. A delay and the inertia trade (on slow
    commands the axis' own lag J/b looks like a delay), and at starts from rest a coarse
    encoder rewards a late start (the axis must cross a count before it shows): an independent
    generator's clean open-loop ramp log on a 1000-count load encoder fitted 52 ms with the
    inertia at 1/60 of the truth; its sliding windows gained 54 % over the same model without
    the delay, and 3 % once each had its own inertia back. This is asked only when the delay
    traded the inertia (the refit without it takes :data:`TRADED_INERTIA_RATIO` times its
    inertia or more).
    """
    sliding = judge.sliding()
    if model.params["delay.seconds"] <= judge.dt or int(sliding.sum()) < MIN_SLIDING_WINDOWS:
        return True
    within_latency = with_values(model, {"delay.seconds": min(model.params["delay.seconds"], judge.dt)})
    if judge.gain_where(judge.score(within_latency), score, sliding) < min_gain:
        return False
    there = judge.subset(sliding)
    # Without the delay the refit also starts from the inertia whose lag J/b is the delay (the
    # trade it tests): from a collapsed inertia it stays in that basin.
    lag_j = model.params["viscous.b"] * (model.params["delay.seconds"] - judge.dt)
    starts = [within_latency]
    if lag_j > model.params["inertia.J"]:
        starts.append(with_values(within_latency, {"inertia.J": lag_j}))
    sse, inertia = [math.inf, math.inf], [0.0, 0.0]
    for i, ms in enumerate((starts, [model])):
        for m in ms:
            fitted, _ = refine(there, m, SLIDING_REFIT, max_evals=SLIDING_REFIT_EVALS)
            for cand in (fitted, m):
                cand_sse = there.score(cand).sse
                if cand_sse < sse[i]:
                    sse[i], inertia[i] = cand_sse, float(cand.params["inertia.J"])
    if inertia[0] < TRADED_INERTIA_RATIO * inertia[1]:
        # Without the delay the rigid body takes no inertia it gave up: nothing traded, and on a
        # coarse encoder the few sliding windows may not tell the two apart (truthgen 6006 dev
        # delay-001: 500 counts at 2 kHz, both refits 0.0548; J 1.46 and 1.41 g·m²).
        return True
    return sse[0] > 0.0 and 1.0 - sse[1] / sse[0] >= min_gain


def resonates_while_sliding(
    judge: KStepJudge, base_score: KStepScore, score: KStepScore, min_gain: float, large_gain: float
) -> bool:
    """Whether a belt also predicts better where the axis slides steadily.

    A belt is a spring between the motor and the load: every change of the command excites it,
    sliding or not. Friction's pre-sliding is a spring too (LuGre's bristles: stiffness σ0,
    damping σ1), but between the axis and the frame, and only at rest and for a short travel
    after a reversal: there a stiff axis rings on it like a load on a belt (an outside
    generator's clean LuGre log, 2 kHz sines: a "belt" of 172 Hz, damping 0.14, against a bristle
    resonance of 260 Hz), and in the windows of steady sliding it is spent. So the belt must
    also win in the windows of steady sliding alone, beyond their own scatter: the paired t of
    its gain over their blocks at least ``MIN_SLIDING_BELT_T``, or (block errors are heavy-tailed:
    a few fast steps dominate, and another missing effect, a ripple, may dominate the sliding
    windows' error) a large share of their error removed, ``large_gain``. That "belt":
    6 % of their error at t = 1.2, against 37 %, t = 3.5, elsewhere; true belts of two
    independent generators, Karnopp and LuGre: 15-92 % at t 2.2-4 or more, 85 % at t = 1.6, and
    46 % at t = 1.1 with a ripple hidden too. Runs with too little steady sliding to tell keep
    the judgement of the whole run.

    The belt must also cut the error of the faster half of those windows (by their slowest
    |ω|, :func:`window_speed`) by ``min_gain``. "Sliding" is two encoder counts per horizon, which
    on a fine encoder is slow enough for friction's own dynamics to act (the bristles relax over
    their deflection z_ss in z_ss/|ω|; the Stribeck curve); these fade with speed, a belt does
    not. The outside generator's seed 17 clean-023 (2 kHz PI-D sines with dither, 16384 counts
    on the motor, LuGre, rigid): a "belt" of 252 Hz, against the base refitted by simulation
    9 % better in all, 7 % at t = 3.1 in the sliding windows (down to 3 mrad/s), 2.8 % in
    their faster half (above 0.96 rad/s); the same log with tanh friction fits no belt. True belts
    of that generator: 12-92 % in the faster half.
    """
    sliding = judge.sliding()
    if int(sliding.sum()) < MIN_SLIDING_WINDOWS:
        return True
    part = judge.subset(sliding)

    def on(s: KStepScore) -> KStepScore:
        return KStepScore(s.window_sse[sliding], s.end_error[sliding], s.fit_percent)

    cmp = part.compare(on(base_score), on(score))
    beyond_scatter = cmp.t_stat >= MIN_SLIDING_BELT_T or cmp.improvement >= large_gain
    return (
        cmp.improvement >= min_gain
        and beyond_scatter
        and resonates_while_fast(judge, base_score, score, min_gain)
    )


def resonates_while_fast(
    judge: KStepJudge, base_score: KStepScore, score: KStepScore, min_gain: float
) -> bool:
    """Whether a belt cuts the error of the faster half of the windows of steady sliding (by
    their slowest |ω|, :func:`window_speed`) by ``min_gain``, where friction's own dynamics are
    weakest (see :func:`resonates_while_sliding`); True with too few such windows to tell."""
    sliding = judge.sliding()
    if int(sliding.sum()) < MIN_SLIDING_WINDOWS:
        return True
    speed = window_speed(judge)
    fast = sliding & (speed > float(np.median(speed[sliding])))
    return judge.gain_where(base_score, score, fast) >= min_gain


def window_speed(judge: KStepJudge) -> FloatArray:
    """The slowest |ω| (rad/s) of each k-step window, from a horizon before its start to its
    end (the span :meth:`KStepJudge.sliding` looks at)."""
    idx = (judge.starts - judge.k)[:, None] + np.arange(2 * judge.k + 1)[None, :]
    om = judge.omega_s[np.clip(idx, 0, judge.omega_s.size - 1)]
    return np.asarray(np.abs(om).min(axis=1), dtype=float)


__all__ = [
    "MIN_SLIDING_WINDOWS",
    "lags_while_sliding",
    "resonates_while_fast",
    "resonates_while_sliding",
    "window_speed",
]
