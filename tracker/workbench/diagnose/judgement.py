"""Judging one candidate effect: does the simulation agree with the screening, and is it physical?

The thresholds and rules of significance live here (see docs/workbench.md, "Diagnosis"); the
orchestration is :func:`tracker.workbench.diagnose.diagnose.diagnose`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from tracker.errors import ConfigError
from tracker.plant.effects import EffectNames, generic_effects, get_effect, get_param
from tracker.plant.effects import compliance as compliance_effect
from tracker.plant.effects import stiction as stiction_effect
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.effect_search import screen_backlash
from tracker.workbench.diagnose.evidence import (
    EvidenceContext,
    ripple_not_repeating,
    saturation_not_where_clipped,
)
from tracker.workbench.diagnose.kstep import (
    Comparison,
    HeldOutSearch,
    KStepJudge,
    KStepScore,
    held_out_search,
    refine,
    with_values,
)
from tracker.workbench.diagnose.screening import Screen, Structure, model_params
from tracker.workbench.diagnose.sliding import lags_while_sliding, resonates_while_sliding
from tracker.workbench.fit import generic
from tracker.workbench.measurements.idim import encoder_timing_s

# A candidate must explain this share of the held-out residual torque (screening) ...
MIN_SCREEN_GAIN = 0.08
MAX_SCREEN_P = 1e-3
MAX_SCREEN_P_JUDGED = 0.05
# ... and cut the k-step prediction error by this share, consistently over blocks of windows.
MIN_KSTEP_GAIN = 0.05
MIN_KSTEP_ROBUST = 0.025
# Stiction is judged on its break-away excess when the moving data cannot see it.
MIN_BREAKAWAY_T = 4.0
MIN_BREAKAWAY_COUNT = 4  # starts from rest needed before their break-away bounds the stiction
REFINE_TOP = 2
MIN_BACKLASH_GAIN = 0.15  # share of the residual torque beyond a count's flicker at reversals
# The k-step error may grow with a backlash (where the load sits in the gap is not observable
# over a short window) but not significantly: a t below minus this is a play that hurts the
# prediction (true gaps of two independent sets: t >= -2.9; a clean log's false gap: -8).
MAX_BACKLASH_KSTEP_WORSE_T = 4.0
# ... nor by its size: the error's scatter hides a prediction that fails outright in a few
# windows (a cascade hunting a count either way at each hold, read as a gap of hundreds of
# counts whose motor swings through it: 11-57 times the error without). The load's unknown
# place in a real gap costs a fraction of the error, not an order of magnitude (true gaps of
# three independent generators: at most 4.7 times).
MAX_BACKLASH_KSTEP_RATIO = 10.0
MIN_DELAY_SAMPLES = 0.5  # below: when in the period the encoder is read (no delay at all)
# Below: one controller tick of computational latency, seen anywhere up to one more sample late
# (when in the period the encoder is read, and the lag of friction's pre-sliding elasticity,
# which a LuGre truth has and the model does not: 1.6-1.7 samples on an independent generator's
# clean logs with a one-sample latency).
MIN_DRIVE_DELAY_SAMPLES = 2.0
MAX_RESONANT_DAMPING = compliance_effect.RESONANT_DAMPING  # |H| of a second-order system peaks below
MIN_CLIPPED_SHARE = 0.002  # a saturation must clip at least this share of the samples
# A command within this share of the log's largest |u| is held at the controller's own clamp.
CLAMP_TOLERANCE = 1e-6
# Clip levels tried by simulation, named by the share of the run's samples each clips.
CLIPPED_SHARES = (0.003, 0.005, 0.01, 0.02, 0.04, 0.08, 0.15, 0.25)
OVERWHELMING_P = 1e-10
MIN_HALF_GAIN_TWO_MASS = 0.025  # torque effects on a two-mass model: gain on each half of the run
# A torque effect refitted by simulation jointly with the effects already in the model (second
# round): the same bar, on each half of the run, against the present structure refitted alike.
MIN_HALF_GAIN_JOINT = MIN_HALF_GAIN_TWO_MASS
JOINT_REFIT_EVALS = 30
BELT_FREQUENCIES_HZ = (3.0, 4.5, 6.5, 9.0, 12.0, 16.0, 22.0, 30.0, 42.0, 60.0)
BELT_DAMPINGS = (0.05, 0.15, 0.4)
EFFECT_PARAMS = {"gravity": 2, "ripple": 3, "stiction": 2, "compliance": 2}
MIN_HELD_OUT_GAIN = 0.05
# A richer effect beats a simpler look-alike by simulation alone when it removes this share of
# the simpler one's k-step error (half of it without the best blocks; some on each half).
PARSIMONY_SIM_GAIN = 0.25
# A torque of position with more parameters than a look-alike that is constant (gravity over a
# short travel is a bias plus a slope): the richer one leads when, with both refitted by simulation
# on one half of the run, it predicts the other half better by this share, on each half.
POSITION_LOOK_ALIKES = {"gravity": ("offset", "coulomb_asymmetry")}
LOOK_ALIKE_REFIT_EVALS = 30
# What each refits on a half: its own parameters, and Coulomb friction for the asymmetry (which
# splits it); the rest of the model keeps its values.
LOOK_ALIKE_REFIT = {
    "gravity": ("gravity",),
    "offset": ("offset",),
    "coulomb_asymmetry": ("coulomb_asymmetry", "coulomb"),
}
STICTION_RATIOS = (1.1, 1.25, 1.4, 1.6, 1.8, 2.0, 2.4)  # break-away / Coulomb tried by simulation
STRIBECK_VELOCITIES = (0.02, 0.05, 0.1)  # rad/s
DELAY_SAMPLES = (0.5, 1, 1.5, 2, 3, 4, 6, 8, 11, 16, 22, 32, 45, 64, 90)  # delays tried by simulation
BUILTIN_TORQUE_EFFECTS = ("offset", "coulomb_asymmetry", "viscous_asymmetry", "gravity", "ripple")
# Judged by the torque regression: the built-in ones and every generic effect (live view).
TORQUE_EFFECTS = EffectNames(lambda: (*BUILTIN_TORQUE_EFFECTS, *generic_effects()))
# Torque-type effects keep their inverse-dynamics parameters (a direct regression on the torque
# is more accurate than a k-step refit); these act through the simulation and are refitted.
REFINED_BY_SIMULATION = ("stiction", "delay", "saturation", "compliance")
# A belt the 30 ms windows do not establish is refitted on windows that count this many periods
# of its resonance after their settling third (:func:`_belt_over_periods`): a decay is seen swing
# by swing.
RESONANCE_PERIODS = 2.0
HIDDEN_STATE_EFFECTS = ("compliance",)


@dataclass(slots=True)
class Judged:
    """One candidate under judgement (mutable: refits replace its model, score and comparison)."""

    effect: str
    screen: Screen
    model: AxisModel
    score: KStepScore
    cmp: Comparison
    significant: bool
    screen_ok: bool
    stderr: dict[str, float] = field(default_factory=dict)
    passed: bool = False  # passed the gates of size and agreement (before the physics check)
    established: str | None = None  # stiction: what the break-away from rest establishes alone
    # Held-out gains (one per half of the run) over a simpler look-alike, by its name (rank()).
    versus: dict[str, tuple[float, float]] = field(default_factory=dict)
    # Why it is no larger than the log's slow disturbance makes of its torque (diagnose()).
    within_disturbance: str | None = None
    # A delay: why it is no longer than a latency the log can tell apart
    # (refitted_base._within_latency).
    within_latency: str | None = None

    def rank_key(self) -> tuple[bool, float]:
        """Significant first, then by the k-step gain: the simulation is the judge.

        The screening's torque gain is a gate, not a rank: inverse dynamics on a coarse encoder
        or near rest (stiction, saturation at the steps) can credit an effect with torque the
        simulation shows it does not predict.
        """
        return (not self.significant, -self.cmp.improvement)

    @property
    def n_params(self) -> int:
        return EFFECT_PARAMS.get(self.effect) or generic.param_count(self.effect)


def _effect_only(scr: Screen) -> Screen:
    """``scr`` with only the new effect's own parameters (the base model keeps its values)."""
    own = {k: v for k, v in scr.params.items() if k.split(".")[0] == scr.effect}
    return replace(scr, params=own)


def _torque_terms_only(scr: Screen, base: AxisModel) -> Screen | None:
    """``scr`` without the regression's values of the present effects that act through the
    simulation (a second round), or None when it has none.

    The torque regression measures what acts on the moving axis — the rigid body and torques
    of position or direction — but not what acts at rest or through the command: a present
    static friction's break-away is barely seen by moving data (the axis leaves the Stribeck
    zone within a few ms), so the regression's joint value is a guess that the present
    structure's refit by simulation knows better. Each parameter is taken from the stage that
    measures it: the base and the new effect from the regression, the present stiction (delay,
    clip) from the k-step refit (a dead band or a belt keeps its own second round). Without
    this, a second round chose between the regression's joint values with a wrong break-away
    (stiction+gravity: 0.070 N·m against 0.100 true and 0.121 refitted) and the new effect
    alone on a base whose inertia and viscous friction had absorbed the missing torque (twice
    and twenty times the truth).
    """
    dropped = [e for e in base.effects if e not in TORQUE_EFFECTS]
    if not dropped:
        return None
    kept = {k: v for k, v in scr.params.items() if k.split(".")[0] not in dropped}
    if len(kept) == len(scr.params):
        return None
    return replace(scr, params=kept)


def _centred(scr: Screen, base: AxisModel) -> Screen:
    """For an asymmetry: split the regression's difference between the directions evenly around
    the base model's value (which averaged the two directions before the asymmetry was known)."""
    pairs = {
        "coulomb_asymmetry": ("coulomb.torque", "negative"),
        "viscous_asymmetry": ("viscous.b", "negative"),
    }
    if scr.effect not in pairs:
        return _effect_only(scr)
    pos_key, neg = pairs[scr.effect]
    neg_key = f"{scr.effect}.{neg}"
    delta = scr.params[neg_key] - scr.params.get(pos_key, base.params[pos_key])
    mid = base.params[pos_key]
    values = {pos_key: max(mid - 0.5 * delta, 0.0), neg_key: max(mid + 0.5 * delta, 0.0)}
    return replace(scr, params=values)


def _candidate_model(model: AxisModel, scr: Screen, ctx: EvidenceContext) -> AxisModel:
    values = dict(scr.params)
    excess = breakaway_over_sliding(ctx) if scr.effect == "stiction" else None
    if excess is not None and excess[0] > MIN_BREAKAWAY_T * excess[1]:
        fc = values.get("coulomb.torque", model.params["coulomb.torque"])
        values["stiction.static_torque"] = max(values["stiction.static_torque"], fc + excess[0])
    if scr.effect == "stiction" and ctx.rests is not None and ctx.rests.established() is not None:
        # The rests that held bound the break-away from below: start the model there.
        values["stiction.static_torque"] = max(values["stiction.static_torque"], ctx.rests.level_nm)
    return with_values(model, values, add=scr.effect)


def judge_candidate(
    scr: Screen,
    screens: Mapping[str, Screen],
    judge: KStepJudge,
    base_model: AxisModel,
    base_score: KStepScore,
    ctx: EvidenceContext,
    two_mass: bool,
    cancel: Callable[[], bool] | None,
    present: bool = False,
    sensor_sse: float = 0.0,
    second_round: bool = False,
) -> Judged:
    """Build the candidate model of ``scr``'s effect and decide whether it is significant.

    ``present``: the model already has effects (a second round), so ``base_model`` is the present
    structure refitted by simulation (:func:`refit_present_structure`), and a torque effect the
    screening supports is also refitted by simulation together with it (:func:`_refit_jointly`).
    A torque effect's screening share is judged beyond ``sensor_sse``, the encoder's own part of
    the residual torque (:func:`_screen_gain`; 0 on a two-mass model). ``second_round``: the
    user's model had effects (not the first round's look again with a computational latency
    added): the candidate is also tried with each parameter from the stage that measures it
    (:func:`_torque_terms_only`).
    """
    effect = scr.effect
    cand = _candidate_model(base_model, scr, ctx)
    score = judge.score(cand)
    # Another missing effect can bias the regression's J, b, Fc (a delay shrinks the apparent
    # inertia): also try the effect alone on the base model's values, keep the better.
    variants = [_effect_only(scr)]
    torque_terms = _torque_terms_only(scr, base_model) if present and second_round else None
    if torque_terms is not None:
        variants.append(torque_terms)
    if scr.effect in ("coulomb_asymmetry", "viscous_asymmetry"):
        variants.append(_centred(scr, base_model))
    for variant in variants:
        other = _candidate_model(base_model, variant, ctx)
        other_score = judge.score(other)
        if other_score.sse < score.sse:
            cand, score = other, other_score
    cmp = judge.compare(base_score, score)
    # Torque effects must pass a strict F-test; the others must also win the k-step judgement
    # by a margin, so a looser one suffices (another missing effect left in the residual
    # shrinks its effective sample size).
    max_p = MAX_SCREEN_P if effect in TORQUE_EFFECTS else MAX_SCREEN_P_JUDGED
    share = _screen_gain(scr, ctx, sensor_sse)
    screen_ok = share >= MIN_SCREEN_GAIN and scr.p_value <= max_p and scr.folds_improve
    if effect == "stiction":
        # Moving data barely sees static friction (the axis leaves the Stribeck zone in a few
        # ms): search the break-away torque by simulation, chosen and judged on halves.
        search = _stiction_search(judge, base_model, base_score, cand)
        if search.held_out_gain > cmp.improvement:
            cand, score = search.best, judge.score(search.best)
            cmp = judge.compare(base_score, score)
        # The break-away judged over the Coulomb torque of the moving data, as
        # :func:`stiction_at_rest` does: the base model may be the user's own values (when the
        # regression predicts worse), and a Coulomb torque below the data's makes every start
        # look late by the difference (6006 dev delay-001: the defaults' Coulomb 18 % low).
        # (A constant lag of the starts does not veto it: on closed-loop lead-lag starts the
        # level story can fit worse than a lag though static friction is there, 6006 dev
        # stiction-005; the delay then competes by simulation, refitted: see below.)
        excess = breakaway_over_sliding(ctx)
        by_breakaway = excess is not None and excess[0] > MIN_BREAKAWAY_T * excess[1]
        # ... or the starts' times follow a break-away level, beyond a constant lag (with the
        # model's delay applied, if it has one: a stiction paired with a delay).
        by_lags = ctx.start_lags is not None and ctx.start_lags.favours_level()
        screen_ok = screen_ok or min(search.gains) >= MIN_HELD_OUT_GAIN or by_breakaway or by_lags
    if effect == "delay":
        # In closed loop the command answers the disturbance a little later, which biases the
        # regression's alignment of the whole input: judge the delay by simulation as well, on
        # a grid of whole and half samples, chosen and judged on halves of the run.
        search = _delay_search(judge, base_model, base_score, cand)
        if search.held_out_gain > cmp.improvement:
            cand, score = search.best, judge.score(search.best)
            cmp = judge.compare(base_score, score)
        # The starts' times say a constant lag: the grid above sits on the base model's inertia,
        # which trades with a delay; let the refit by simulation judge it (6006 dev delay-001).
        # Starts whose lag follows a break-away level (long after a creeping torque, short after
        # a step) are static friction's, not a delay's: the grid's gain alone does not pass then.
        by_lags = ctx.start_lags is not None and ctx.start_lags.favours_delay()
        leveled = ctx.start_lags is not None and ctx.start_lags.favours_level()
        by_search = min(search.gains) >= MIN_HELD_OUT_GAIN and not leveled
        screen_ok = screen_ok or by_search or by_lags
    if effect == "saturation":
        # The regression's clip level is chosen on the residual torque, which another missing
        # torque can dominate (gravity held by the loop's command: a clip at the holding level
        # "explains" it); a clip acts on the command, so search it by simulation too, on levels
        # named by the share of the run they clip, chosen and judged on halves of the run. A
        # level the simulation alone chose must pass the bar of evidence by simulation alone
        # (a quarter of the error, on each held-out half): a clip a little above the typical
        # command trims the few largest steps, which a coarse encoder or another friction law
        # can reward by 7-10 % on a log with no clip at all. Nor may the torque contradict it:
        # a clip takes torque away at the samples beyond it, which inverse dynamics measures
        # there; when the regression's best level leaves more held-out residual torque than no
        # clip at all, the drive delivered what was asked, and what the simulation rewards is
        # another dynamic of the largest steps that trimming them imitates (outside generator
        # seed 19, clean-024: a drive with no rail but a 0.5 ms current lag, steps of 11 V; a
        # clip at 8.1 V cut the k-step error by 83 % and explained -38 % of the held-out
        # residual torque).
        clips = _saturation_search(judge, base_model, base_score, cand, ctx)
        if clips is not None and min(clips.gains) >= PARSIMONY_SIM_GAIN and scr.gain_cv > 0.0:
            if clips.held_out_gain > cmp.improvement:
                cand, score = clips.best, judge.score(clips.best)
                cmp = judge.compare(base_score, score)
            screen_ok = True
    if effect == "compliance":
        # A soft belt (load resonance inside the control loop's band) defeats the torque
        # regression, and the regression's damping is rough: search the belt by simulation
        # too (around the screening's frequency as well), chosen and judged on halves.
        f_screen = float(cand.params["compliance.frequency"])
        freqs = sorted({*BELT_FREQUENCIES_HZ, *(f_screen * r for r in (0.8, 0.9, 1.0, 1.1, 1.25))})
        search = held_out_search(
            judge,
            base_score,
            [
                with_values(
                    base_model, {"compliance.frequency": f, "compliance.damping": z}, add="compliance"
                )
                for f in freqs
                if f < get_param("compliance.frequency").upper
                for z in BELT_DAMPINGS
            ],
        )
        if search.held_out_gain > cmp.improvement or not _physical(effect, cand, ctx):
            cand, score = search.best, judge.score(search.best)
            cmp = judge.compare(base_score, score)
        screen_ok = (screen_ok and _physical(effect, cand, ctx)) or min(search.gains) >= MIN_HELD_OUT_GAIN
    # A torque of position alone acts wherever the axis goes, over the whole run: its gain must
    # not hinge on a few blocks, however overwhelming the torque regression.
    overwhelming_p = scr.p_value if not _acts_everywhere(effect, cand, ctx) else 1.0
    significant = screen_ok and kstep_ok(effect, cmp, overwhelming_p)
    if effect == "backlash":
        significant = _backlash_significant(scr, screens, cmp)
    elif not screen_ok and two_mass and effect in TORQUE_EFFECTS and cmp.improvement > 0:
        # With a belt or dead band in the model the torque regression is swamped by the rough
        # load reconstruction: refit the effect with the friction by simulation and judge it
        # on held-out halves of the k-step error.
        names = [k for k in cand.params if k.split(".")[0] in (effect, "viscous", "coulomb")]
        cand, _ = refine(judge, cand, names, max_evals=20, cancel=cancel)
        score = judge.score(cand)
        cmp = judge.compare(base_score, score)
        significant = min(judge.half_gains(base_score, score)) >= MIN_HALF_GAIN_TWO_MASS and kstep_ok(
            effect, cmp
        )
    elif present and screen_ok and effect in TORQUE_EFFECTS and (second_round or not significant):
        # A second round: the present effect's values were fitted without the missing one and
        # took part of it (a clip placed where it imitates a holding torque, an inertia that took
        # an unbalance), so every torque candidate the screening supports is judged with them
        # refitted alongside it, not only one that failed: significant look-alikes are then
        # ranked on like terms (seed 9393 saturation+gravity-000: the clip fitted at 4.47 V, true
        # 2.35; gravity on it cut the k-step error by 17 %, a bias by 22 %, named "offset";
        # refitted jointly, gravity 0.026 against the bias's 0.052, the clip at 2.35 V).
        joint, joint_score = refit_jointly(judge, base_model, cand, cancel)
        joint_cmp = judge.compare(base_score, joint_score)
        if joint_score.sse < score.sse:
            cand, score, cmp = joint, joint_score, joint_cmp
            significant = significant or (
                min(judge.half_gains(base_score, score)) >= MIN_HALF_GAIN_JOINT and kstep_ok(effect, cmp)
            )
    passed = significant
    significant = significant and _physical(effect, cand, ctx) and negligible(effect, cand, ctx) is None
    if significant:
        significant = _holds_while_sliding(effect, judge, cand, base_score, score)
    established = stiction_at_rest(ctx) if effect == "stiction" else None
    if established is not None and negligible(effect, cand, ctx) is None:
        screen_ok = passed = significant = True
    return Judged(
        effect, scr, cand, score, cmp, significant, screen_ok, passed=passed, established=established
    )


def _screen_gain(scr: Screen, ctx: EvidenceContext, sensor_sse: float) -> float:
    """The share of the residual torque the screening credits ``scr`` with, for its bar.

    For a torque effect on a rigid model: the share of what is left beyond the sensor
    (``sensor_sse``, :func:`tracker.workbench.diagnose.sensor_floor.sensor_torque_sse`); else the
    share of the held-out residual torque (``gain_cv``). Once the first effect is in the model,
    the encoder's own torque is most of the residual on a coarse or fast-sampled encoder (55-63 %
    on the seed-9393 pairs traced), and a second effect as real as the first clears a bar on a
    share of mostly sensor only when it is large. So it is in a first round on a coarse encoder,
    where the regression's inertia shrinks under the noise of α and leaves the inertial torque in
    the residual too (9191 held-out coulomb_asymmetry-007, 500 counts per revolution at 250 Hz: a
    47 % Coulomb asymmetry explained 4 % of the residual torque, 18 % of what the encoder leaves
    explainable; the k-step error fell 4 % with it, t = 4.2). A torque effect's columns
    (functions of θ and of the direction of motion) cannot follow that high-frequency torque, so
    what they explain comes out of the rest. The hidden-state effects (a dead band, a belt)
    filter α itself and can explain sensor torque: they keep their own bars. The disturbance
    stays in the rest, so the bar is not lowered for it.
    """
    if sensor_sse <= 0.0 or scr.effect not in TORQUE_EFFECTS:
        return scr.gain_cv
    base_sse = ctx.base_reg.sse_cv
    beyond = base_sse - sensor_sse
    if base_sse <= 0.0 or beyond <= 0.0:
        return scr.gain_cv
    return max(scr.gain_cv, scr.gain_cv * base_sse / beyond)


def stiction_at_rest(ctx: EvidenceContext) -> str | None:
    """What the break-away from rest establishes about static friction by itself, or None.

    The break-away analysis measures the excess over the base model's Coulomb torque; a missing
    stiction biases that Coulomb (the model fitted to the whole run absorbs some break-away), so
    the excess is taken over the Coulomb torque of the torque regression on the moving data
    instead, and judged by the stiction effect's own rule
    (:func:`tracker.plant.effects.stiction.established_at_rest`).
    """
    held = ctx.rests.established() if ctx.rests is not None else None
    ba = ctx.breakaway
    measured = breakaway_over_sliding(ctx)
    if ba is None or measured is None or ba.count <= MIN_BREAKAWAY_COUNT:
        return held
    excess, se = measured
    if excess / se < MIN_BREAKAWAY_T or ba.one_sided() is not None:
        return held
    sliding = ba.static_excess_nm + ba.coulomb_nm - excess
    lower = excess - float(stats.t.ppf(0.975, ba.count - 2)) * se
    return stiction_effect.established_at_rest(sliding, excess, lower) or held


def breakaway_over_sliding(ctx: EvidenceContext) -> tuple[float, float] | None:
    """The break-away's excess over the Coulomb torque of the torque regression on the moving
    data, and its standard error (N·m); None without a break-away measurement.

    The break-away analysis measures the excess over the base model's Coulomb torque, which is
    the user's own value when the regression predicted worse, or one that absorbed part of a
    missing break-away: either way not the sliding friction the data show.

    The standard error combines the break-away's scatter over the starts with the regression's
    standard error of that sliding Coulomb torque: the excess is a difference of two estimates,
    and a log with few moving samples determines Coulomb poorly (an outside generator's clean
    step log on a 1000-count encoder: 176 usable samples, Coulomb 0.012 ± 0.005 N·m, truly 0.024).
    A friction whose transition at low speed is richer than Coulomb's switch (LuGre's pre-sliding
    bristles) pulls that estimate lower still, and the starts then looked like static friction
    (+0.012 ± 0.002 N·m over a Coulomb the log never pinned down).
    """
    ba = ctx.breakaway
    if ba is None or not ba.static_excess_se > 0:
        return None
    if ctx.sliding_coulomb is not None:
        sliding, sliding_se = ctx.sliding_coulomb
    else:
        values, stderr = model_params(ctx.model, Structure.of(ctx.model), ctx.base_reg)
        sliding = float(values["coulomb.torque"])
        sliding_se = float(stderr.get("coulomb.torque", 0.0))
    se = math.hypot(ba.static_excess_se, sliding_se) if math.isfinite(sliding_se) else ba.static_excess_se
    return ba.static_excess_nm + ba.coulomb_nm - sliding, se


def refit_present_structure(
    judge: KStepJudge, model: AxisModel, score: KStepScore, cancel: Callable[[], bool] | None
) -> tuple[AxisModel, KStepScore]:
    """The model with its base and effects' parameters refitted by the k-step error (or the
    model itself when the refit predicts no better).

    A model that already has an effect was fitted with it, by a loss other than the judge's;
    its effect's parameters trade with the base's (a bias torque with gravity's value at the
    working angle, a delay with the inertia). Candidates judged against it unrefitted are
    credited with the refit's own gain, and searched on values that absorbed part of them.
    """
    refitted, _ = refine(judge, model, model.free_param_names(), cancel=cancel)
    refitted_score = judge.score(refitted)
    return (refitted, refitted_score) if refitted_score.sse < score.sse else (model, score)


def refit_jointly(
    judge: KStepJudge, base: AxisModel, cand: AxisModel, cancel: Callable[[], bool] | None
) -> tuple[AxisModel, KStepScore]:
    """A torque effect refitted by simulation together with every parameter already present.

    In a second round the torque regression refits the new effect jointly with the present one,
    but where they look alike (gravity's constant part and a bias per direction, which the moving
    samples cannot tell apart) it may trade them to values that hold the axis wrongly at rest;
    the simulation, which has the starts from rest, sorts them out. Starts from the candidate's
    values (the better of the regression's joint ones and the effect's own on the present
    values: :func:`judge_candidate`).
    """
    names = [*base.free_param_names(), *(k for k in cand.free_param_names() if k not in base.params)]
    fitted, _ = refine(judge, cand, names, max_evals=JOINT_REFIT_EVALS, cancel=cancel)
    return fitted, judge.score(fitted)


def refine_leaders(
    rows: list[Judged],
    judge: KStepJudge,
    base_score: KStepScore,
    ctx: EvidenceContext,
    step: Callable[[float], None],
    cancel: Callable[[], bool] | None,
) -> None:
    """Refit by simulation the leading candidates the screening supports (in place).

    Gives the verdict its final parameters and standard errors, and a second chance to effects
    acting through the simulation whose screening values (inertia split, damping) are rough.
    """
    # A hidden-state effect supported by the screening may predict worse before its refit (the
    # inertia split and the rigid body's values come from a rough regression), so it is refined
    # whatever its first k-step score; the others only when they already predict better.
    hopeful = [
        r
        for r in rows
        if r.screen_ok
        and r.effect in REFINED_BY_SIMULATION
        and (r.cmp.improvement > 0 or r.effect in HIDDEN_STATE_EFFECTS)
    ]
    for i, r in enumerate(hopeful[:REFINE_TOP]):
        step(0.7 + 0.1 * i)
        refined, se = refine(judge, r.model, cancel=cancel)
        if r.effect == "compliance" and compliance_effect.unresolved(refined.params, se) is not None:
            refined, se = _belt_over_periods(judge, ctx, refined, se, cancel)
        score = judge.score(refined)
        if score.sse < r.score.sse:
            r.model, r.score, r.cmp, r.stderr = refined, score, judge.compare(base_score, score), se
            r.passed = kstep_ok(r.effect, r.cmp)
            small = negligible(r.effect, refined, ctx) is not None
            r.passed = r.passed or (r.established is not None and not small)
            r.significant = r.passed and _physical(r.effect, refined, ctx) and not small
            if r.effect == "compliance" and compliance_effect.unresolved(refined.params, se) is not None:
                r.significant = False
            if r.significant:
                r.significant = _holds_while_sliding(r.effect, judge, refined, base_score, score)


def _belt_over_periods(
    judge: KStepJudge,
    ctx: EvidenceContext,
    model: AxisModel,
    stderr: dict[str, float],
    cancel: Callable[[], bool] | None,
) -> tuple[AxisModel, dict[str, float]]:
    """A belt whose resonance ``judge``'s windows did not establish (its damping may be above
    1/√2), refitted from ``model`` on windows that count :data:`RESONANCE_PERIODS` periods of the
    resonance after their settling third: that refit when it establishes the resonance, else
    ``model`` and ``stderr`` themselves (also when ``judge``'s windows already count them).

    A damping ratio is read from how fast the resonance decays from one swing to the next; over a
    window shorter than a period the error is nearly flat in it, so there "not established" says
    nothing about the belt (truthgen 7171 held-out compliance-008: a belt of 21.8 Hz, damping
    0.16, refitted at 0.61 ± 0.06 on the 30 ms windows, whose last 20 ms count: "may have no
    resonance peak"; on two periods 0.18 ± 0.06). Only then: where the short windows establish the
    resonance they keep their values, whose many starts read its frequency best (a frequency a
    little off costs the long windows' phase over two periods, and another missing effect drifts
    them: both raise their damping).
    """
    f_hz = float(model.params["compliance.frequency"])
    counted_s = (judge.k - judge.k_settle) * judge.dt
    need_s = RESONANCE_PERIODS / max(f_hz, 1e-6)
    if need_s <= counted_s:
        return model, stderr
    long = KStepJudge(judge.meas, ctx.sig, need_s * judge.k / (judge.k - judge.k_settle))
    refitted, se = refine(long, model, cancel=cancel)
    if compliance_effect.unresolved(refitted.params, se) is not None:
        return model, stderr
    return refitted, se


def reconsider_backlash(rows: list[Judged], screens: Mapping[str, Screen], ctx: EvidenceContext) -> None:
    """A belt that the simulation rejects does not out-explain a dead band (in place)."""
    by = {r.effect: r for r in rows}
    bl, belt = by.get("backlash"), by.get("compliance")
    if bl is None or bl.significant or belt is None or belt.significant:
        return
    others = {k: v for k, v in screens.items() if k != "compliance"}
    bl.significant = _backlash_significant(bl.screen, others, bl.cmp) and _physical("backlash", bl.model, ctx)


def rank(
    rows: list[Judged],
    judge: KStepJudge,
    ctx: EvidenceContext | None = None,
    screens: Mapping[str, Screen] | None = None,
) -> None:
    """Best first (in place); a bias torque ahead of its equivalent direction-dependent friction.

    Parsimony: a significant leader with more parameters than a significant look-alike (gravity
    over a small range imitates a bias torque) leads only if it explains significantly more of
    the torque (F-test on the effective sample size) and also predicts better by simulation;
    otherwise the simpler story leads.

    Backlash is judged by the screening alone (the k-step prediction cannot see where the load
    sits in the dead band), so among the significant it is placed by the screening too: ahead of
    every significant candidate whose torque regression explains less of the held-out torque (a
    delay or a belt imitates the late load at reversals, but explains less of it), and whose
    effect, once in the regression, leaves the dead band its evidence (:func:`_play_beyond`;
    with ``ctx``).
    """
    rows.sort(key=Judged.rank_key)
    bl = next((i for i, r in enumerate(rows) if r.effect == "backlash" and r.significant), None)
    if bl is not None:
        ahead = next(
            (
                i
                for i in range(bl)
                if rows[i].screen.gain_cv < rows[bl].screen.gain_cv
                and (ctx is None or _play_beyond(rows[bl], rows[i], screens or {}, ctx))
            ),
            None,
        )
        if ahead is not None:
            rows.insert(ahead, rows.pop(bl))
    if rows and rows[0].significant:
        # A simpler look-alike leads (its k-step gain at the regression's values is larger):
        # the richer torque of position leads instead when the log determines it.
        rich = next(
            (r for r in rows if r.significant and _look_alike(r, rows[0])),
            None,
        )
        if rich is not None and min(_versus(rich, rows[0], judge)) >= MIN_HELD_OUT_GAIN:
            rows.insert(0, rows.pop(rows.index(rich)))
    for j in range(1, len(rows)):
        top, other = rows[0], rows[j]
        if not other.significant:
            break
        if other.n_params < top.n_params and not _explains_more(top, other, judge):
            rows[0], rows[j] = other, top
    names = [r.effect for r in rows]
    if "offset" in names and "coulomb_asymmetry" in names:
        i, j = names.index("coulomb_asymmetry"), names.index("offset")
        if i < j and rows[i].significant == rows[j].significant:
            gi, gj = rows[i].cmp.improvement, rows[j].cmp.improvement
            if gj >= gi - 0.02 * max(abs(gi), 1e-9) - 0.01:
                rows[i], rows[j] = rows[j], rows[i]


def promote_angle_dependence(
    rows: list[Judged], judge: KStepJudge, base_score: KStepScore, ctx: EvidenceContext
) -> bool:
    """Let a torque of position whose regression failed compete with the constant look-alike
    that leads (in place; True when it now leads).

    A bias torque is the same at every angle; gravity, ``T_g·sin(θ + φ)``, changes with the angle
    in either direction of motion. When a bias (or its equivalent Coulomb asymmetry) is named,
    the torque is there; which shape it has is what held-out prediction decides
    (:func:`_versus`), and that needs no torque regression of gravity's own: another missing
    effect acting through the command (a drive delay in an open-loop chirp) can wreck the
    regression's sin θ, cos θ columns while the simulation still follows the angle (truthgen
    8181 gravity+delay-003: gravity's regression explained −48 % of the held-out torque at
    0.038 N·m, the bias +58 %; refitted by simulation gravity came out at its true 0.078 N·m
    over the 1.9 rad travel). Such a gravity — predicting better by simulation, as a torque effect
    must — is refitted by simulation on the whole run and leads when it predicts each held-out
    half better than the bias by :data:`MIN_HELD_OUT_GAIN`, the bar a significant gravity meets.
    """
    lead = rows[0] if rows else None
    if lead is None or not lead.significant:
        return False
    for r in rows:
        if r.significant or r.screen_ok or not _look_alike(r, lead) or not kstep_ok(r.effect, r.cmp):
            continue
        names = [k for k in r.model.free_param_names() if k.split(".")[0] in LOOK_ALIKE_REFIT[r.effect]]
        fitted, se = refine(judge, r.model, names, max_evals=LOOK_ALIKE_REFIT_EVALS)
        score = judge.score(fitted)
        if score.sse >= lead.score.sse:
            continue
        r.model, r.score, r.cmp, r.stderr = fitted, score, judge.compare(base_score, score), se
        r.versus.clear()
        if min(_versus(r, lead, judge)) >= MIN_HELD_OUT_GAIN and _physical(r.effect, fitted, ctx):
            r.passed = r.significant = True
            rows.insert(0, rows.pop(rows.index(r)))
            return True
    return False


def _delay_search(
    judge: KStepJudge, base: AxisModel, base_score: KStepScore, cand: AxisModel
) -> HeldOutSearch:
    dt = judge.dt
    grid = {round(cand.params["delay.seconds"] / dt * 2) / 2, *DELAY_SAMPLES}
    seconds = sorted(v * dt for v in grid if 0 < v * dt <= get_param("delay.seconds").upper)
    return held_out_search(
        judge, base_score, [with_values(base, {"delay.seconds": d}, add="delay") for d in seconds]
    )


def _saturation_search(
    judge: KStepJudge, base: AxisModel, base_score: KStepScore, cand: AxisModel, ctx: EvidenceContext
) -> HeldOutSearch | None:
    """Clip levels by simulation: the screening's and those clipping :data:`CLIPPED_SHARES` of
    the run's commands (None when the command never goes beyond the lowest such level)."""
    au = np.abs(ctx.sig.u_v)
    upper = get_param("saturation.limit").upper
    levels = {float(np.quantile(au, 1.0 - share)) for share in CLIPPED_SHARES}
    levels.add(float(cand.params["saturation.limit"]))
    grid = sorted(v for v in levels if v > 0.0 and v < min(upper, float(au.max())))
    if not grid:
        return None
    return held_out_search(
        judge, base_score, [with_values(base, {"saturation.limit": v}, add="saturation") for v in grid]
    )


def _holds_while_sliding(
    effect: str, judge: KStepJudge, model: AxisModel, base_score: KStepScore, score: KStepScore
) -> bool:
    """Whether a delay or a belt (``model``, scoring ``score``) also wins where the axis slides
    steadily (:mod:`.sliding`); True for the other effects."""
    if effect == "delay":
        return lags_while_sliding(judge, model, score, MIN_KSTEP_GAIN)
    if effect == "compliance":
        return resonates_while_sliding(judge, base_score, score, MIN_KSTEP_GAIN, PARSIMONY_SIM_GAIN)
    return True


def _explains_more(rich: Judged, simple: Judged, judge: KStepJudge) -> bool:
    """Whether ``rich`` (more parameters) explains significantly more than ``simple``.

    Either by an F-test on the torque (effective sample size) confirmed by simulation, or by
    simulation alone when it removes a large share of the simple story's remaining k-step error
    on each half of the run (stiction against a delay: the torque regression barely sees
    static friction, the simulation of starts from rest does).
    """
    if _look_alike(rich, simple):
        held_out = _versus(rich, simple, judge)
        if min(held_out) >= MIN_HELD_OUT_GAIN:
            return True
        if min(held_out) <= 0.0:
            # Refitted on one half, the richer story predicts the other no better than the
            # simpler one: its extra torque regression gain is that half's noise, not a slope
            # the log determines (the held-out rule decides; the torque's F-test may only name
            # it where every held-out half agrees, however slightly).
            return False
    by_sim = judge.compare(simple.score, rich.score)
    if by_sim.improvement >= PARSIMONY_SIM_GAIN and by_sim.robust_improvement >= 0.5 * PARSIMONY_SIM_GAIN:
        if min(judge.half_gains(simple.score, rich.score)) >= MIN_HELD_OUT_GAIN:
            return True
    r, q = rich.screen.regression, simple.screen.regression
    extra = max(1, rich.n_params - simple.n_params)
    dof = max(1.0, r.n_eff - len(r.names))
    if r.sse <= 0.0 or q.sse <= r.sse:
        return False
    f = ((q.sse - r.sse) / extra) / (r.sse / dof)
    better_torque = float(stats.f.sf(f, extra, dof)) < MAX_SCREEN_P
    return better_torque and rich.score.sse < simple.score.sse


def _play_beyond(bl: Judged, other: Judged, screens: Mapping[str, Screen], ctx: EvidenceContext) -> bool:
    """Whether the dead band still passes its screening bar with ``other``'s effect in the
    regression: a missing torque the dead band's coasting load partly imitates (an unbalance
    that the load's late arrival at each reversal follows) leaves it nothing of its own."""
    if other.effect in ("backlash", "compliance"):
        return True
    scr = screen_backlash(ctx.design, ctx.model, other.screen.structure, other.screen.regression)
    return _backlash_significant(scr, screens, bl.cmp)


def _look_alike(rich: Judged, simple: Judged) -> bool:
    """Whether ``rich`` is a torque of position that ``simple`` imitates over a short travel, on a
    rigid model (a belt's or dead band's windows are shot from several hidden starts, ten times
    the cost of the halves' refits; their torque effects have their own path)."""
    two_mass = rich.model.has("backlash") or rich.model.has("compliance")
    return not two_mass and simple.effect in POSITION_LOOK_ALIKES.get(rich.effect, ())


def _versus(rich: Judged, simple: Judged, judge: KStepJudge) -> tuple[float, float]:
    """How much better ``rich`` predicts than its look-alike ``simple`` on held-out halves.

    Each is refitted by simulation (its own parameters, :data:`LOOK_ALIKE_REFIT`) on one half of
    the run (alternating 1 s blocks) and scored on the other: over a
    short travel gravity is a bias torque plus a slope, and what the log determines is whether
    that slope (and curvature) predicts data it was not fitted on. Returns the share of the
    simple one's held-out error removed, per half; remembered on ``rich`` (against the first
    look-alike compared: a bias torque and direction-dependent Coulomb friction are one story).
    """
    if rich.versus:  # offset and coulomb_asymmetry are one story on a rigid axis: compared once
        return next(iter(rich.versus.values()))
    half = judge.halves()
    sse: dict[str, list[float]] = {}
    for row in (rich, simple):
        names = [k for k in row.model.free_param_names() if k.split(".")[0] in LOOK_ALIKE_REFIT[row.effect]]
        sse[row.effect] = []
        for h in (0, 1):
            fitted, _ = refine(judge.subset(half == h), row.model, names, max_evals=LOOK_ALIKE_REFIT_EVALS)
            sse[row.effect].append(judge.subset(half != h).score(fitted).sse)
    gains = tuple(
        1.0 - r / q if q > 0 else 0.0 for r, q in zip(sse[rich.effect], sse[simple.effect], strict=True)
    )
    rich.versus[simple.effect] = (gains[0], gains[1])
    return rich.versus[simple.effect]


def look_alike_notes(rows: list[Judged]) -> tuple[str, ...]:
    """What the held-out comparison of a torque of position with its simpler look-alike found
    (:func:`rank`): which one the log determines, or that it cannot tell them apart."""
    notes = []
    lead = rows[0].effect if rows else None
    for r in rows:
        for simple, (g0, g1) in r.versus.items():
            figures = (
                f"refitted by simulation on one half of the run and judged on the other, {r.effect} "
                f"changes {simple}'s k-step error by {-100 * g0:+.0f} % and {-100 * g1:+.0f} % "
                f"(naming {r.effect} needs -{100 * MIN_HELD_OUT_GAIN:.0f} % or better on each half, "
                "or a torque regression that explains significantly more and no half worse)"
            )
            if min(g0, g1) >= MIN_HELD_OUT_GAIN:
                notes.append(f"{r.effect} rather than {simple}: {figures}")
            elif max(g0, g1) <= -MIN_HELD_OUT_GAIN:
                # The ranking follows it (a worse held-out half: the simpler one leads).
                notes.append(f"the held-out halves favour {simple} over {r.effect}: {figures}")
            else:
                experiment = get_effect(r.effect).experiment or ""
                notes.append(
                    f"{r.effect} and {simple} look alike on this log, which cannot tell them apart "
                    f"(named: {lead}): {figures}. To tell them apart: {experiment}"
                )
    return tuple(notes)


def _stiction_search(
    judge: KStepJudge, base: AxisModel, base_score: KStepScore, cand: AxisModel
) -> HeldOutSearch:
    fc = cand.params["coulomb.torque"]
    grid = []
    for ratio in STICTION_RATIOS:
        for vs in STRIBECK_VELOCITIES:
            grid.append(
                with_values(
                    base, {"stiction.static_torque": fc * ratio, "stiction.velocity": vs}, add="stiction"
                )
            )
    return held_out_search(judge, base_score, grid)


def _physical(effect: str, model: AxisModel, ctx: EvidenceContext) -> bool:
    """False for values that are no physical effect.

    A delay under half a sample period is the sampling convention (when in the period the
    encoder is read); a delay of about one sample is the controller's own computational latency
    (the command logged at row i applied from row i + 1), a property of the log, not of the
    drive — reported apart (:func:`finding`). A clip level the command never reaches clips
    nothing (its gain came from refitting the rest); nor does one the command passes only where
    the controller held it at its own clamp (the log's largest |u|, the same value sample after
    sample): there the command does not grow, so nothing shows the torque stop growing with it,
    and any lag of the largest steps (an armature's L/R) reads as a clip just under the clamp. One
    whose clipped samples carry no more of the residual torque than their share of the time
    explains nothing a clip would (:func:`tracker.plant.effects.saturation.not_where_clipped`). A
    "belt" with a damping ratio of 1/√2 or more has no resonance peak, and one at or above a
    quarter of the sampling rate or the
    catalogue's bound cannot be resolved: both are the model's extra load state fitting noise.
    A ripple must be seen to repeat: fitted on one half of the angles the run covers, it must
    predict the other half (:func:`tracker.plant.effects.ripple.not_repeating`); else it is a
    smooth torque of position, not a periodic one.
    """
    if effect == "ripple":
        return ripple_not_repeating(float(model.params["ripple.cycles_per_rev"]), ctx) is None
    if effect == "delay":
        delay_s = model.params["delay.seconds"]
        timing_s = encoder_timing_s(ctx.sig.theta_raw_rad, ctx.sig.dt_s)
        return delay_s >= MIN_DRIVE_DELAY_SAMPLES * ctx.sig.dt_s and delay_s >= timing_s
    if effect == "saturation":
        limit = model.params["saturation.limit"]
        u = np.abs(ctx.sig.u_v)
        clamped = u >= (1.0 - CLAMP_TOLERANCE) * float(u.max()) if u.size else u > 0.0
        clipped = float(np.mean((u > limit) & ~clamped))
        return clipped >= MIN_CLIPPED_SHARE and saturation_not_where_clipped(limit, ctx) is None
    if effect == "compliance":
        f_max = min(0.25 / ctx.sig.dt_s, 0.95 * get_param("compliance.frequency").upper)
        return (
            model.params["compliance.damping"] < MAX_RESONANT_DAMPING
            and model.params["compliance.frequency"] < f_max
        )
    return True


def negligible(effect: str, model: AxisModel, ctx: EvidenceContext | None = None) -> str | None:
    """Why the effect's fitted values are too small to be a missing effect (its file says), or None.

    Stiction's fitted break-away is replaced by the level the start times from rest measure when
    those reject it (:meth:`StartLags.rejects_level`). It is also judged on its direct measurement
    when there is one: the break-away from
    rest (:mod:`tracker.workbench.diagnose.breakaway`), whose 95 % upper bound must exceed the
    Stribeck dip's share of Coulomb, whatever break-away the simulation fitted.
    """
    try:
        check = get_effect(effect).negligible
    except ConfigError:
        return None
    params: Mapping[str, float] = model.params
    lags = ctx.start_lags if ctx is not None and effect == "stiction" else None
    if lags is not None and lags.rejects_level(float(params["stiction.static_torque"])):
        # The starts from rest measure the break-away directly and reject the level the
        # simulation fitted (a refit that trades the break-away against Coulomb, or fits the
        # Karnopp stick to something else): judge the size the starts measured, over the
        # Coulomb torque of sliding they were timed against.
        params = {"coulomb.torque": lags.coulomb_nm, "stiction.static_torque": lags.level_nm}
    why = check(params) if check is not None else None
    ba = ctx.breakaway if ctx is not None else None
    if why is None and effect == "stiction" and ba is not None and ba.count > MIN_BREAKAWAY_COUNT:
        upper = ba.static_excess_nm + float(stats.t.ppf(0.975, ba.count - 2)) * ba.static_excess_se
        why = stiction_effect.negligible_at_rest(float(model.params["coulomb.torque"]), upper)
    return why


def finding(row: Judged, ctx: EvidenceContext) -> str | None:
    """What a candidate that is not the verdict still tells: a one-sample computational latency,
    or an effect that is detectable but too small to matter. None when nothing."""
    if row.significant:
        return None
    if row.within_disturbance is not None:
        return "significant but small"
    if row.within_latency is not None:
        return "within a latency"
    if row.effect == "delay" and row.passed:
        samples = row.model.params["delay.seconds"] / ctx.sig.dt_s
        if MIN_DELAY_SAMPLES <= samples < MIN_DRIVE_DELAY_SAMPLES:
            return "computational latency"
        if row.model.params["delay.seconds"] < encoder_timing_s(ctx.sig.theta_raw_rad, ctx.sig.dt_s):
            return "within the encoder's timing"
    if row.passed and _physical(row.effect, row.model, ctx):
        return "significant but small" if negligible(row.effect, row.model, ctx) else None
    scr = row.screen
    detectable = scr.p_value <= MAX_SCREEN_P and scr.folds_improve and scr.gain_cv > 0.0
    agrees = row.cmp.improvement > 0.0 and row.cmp.robust_improvement > 0.0
    if detectable and agrees and _physical(row.effect, row.model, ctx):
        return "significant but small"
    return None


def _acts_everywhere(effect: str, model: AxisModel, ctx: EvidenceContext) -> bool:
    """Whether ``effect`` adds a torque of position alone (gravity, ripple, a bias, a cable's
    drag by angle): the same at rest, slow or fast, either way, so it acts in every part of the
    run, not only in its few fast moves (as a viscous asymmetry does)."""
    if effect not in TORQUE_EFFECTS:
        return False
    sig = ctx.sig
    theta, omega = sig.theta_rad[sig.use], sig.omega_rad_s[sig.use]
    torque = get_effect(effect).torque_nm
    moving = np.asarray(torque(model.params, theta, omega), dtype=float)
    at_rest = np.asarray(torque(model.params, theta, np.zeros_like(omega)), dtype=float)
    scale = float(np.max(np.abs(at_rest))) if at_rest.size else 0.0
    return scale > 0.0 and bool(np.allclose(moving, at_rest, rtol=1e-9, atol=1e-12 * scale))


def kstep_ok(effect: str, cmp: Comparison, screen_p: float = 1.0) -> bool:
    """The simulation agrees with the screening.

    Torque effects are measured best by the torque regression (a small viscous asymmetry
    barely moves a 30 ms prediction, and only in the few fast moves of one direction): the
    simulation must agree in direction, also without its two best blocks unless the regression's
    evidence is overwhelming (``screen_p``; the caller passes 1 for a torque of position alone,
    which acts all through the run: see :func:`_acts_everywhere`). Effects that act through the
    command or a hidden state are where inverse dynamics can be fooled (a clip level or a belt
    fitted to noise): they must win by a margin.
    """
    if effect in TORQUE_EFFECTS:
        return cmp.improvement > 0.0 and (cmp.robust_improvement > 0.0 or screen_p <= OVERWHELMING_P)
    return cmp.improvement >= MIN_KSTEP_GAIN and cmp.robust_improvement >= MIN_KSTEP_ROBUST


def _backlash_significant(scr: Screen, screens: Mapping[str, Screen], cmp: Comparison) -> bool:
    """Backlash by screening alone, with a stricter bar.

    Where the load sits in the dead band is not observable over a short prediction window (a
    load without friction coasts in the gap), so the k-step judgement cannot confirm backlash
    even for the true model. The screening reconstructs the load through the whole run instead;
    it must explain a large share of the torque beyond what a play of a count or two explains
    (the encoder's flicker at reversals: see ``effect_search.screen_backlash``), more of the
    held-out torque than a belt would, and the simulation must not be made significantly worse
    by it (the k-step error's t no lower than ``-MAX_BACKLASH_KSTEP_WORSE_T``: a bar on the
    error's own scatter, not on its size, which a short log's few windows make large either way),
    nor made an order of magnitude worse (``MAX_BACKLASH_KSTEP_RATIO`` times the error without
    it: an effect whose own prediction fails outright is no verdict, however it scatters).
    """
    other = screens.get("compliance")
    # Only a belt with a resonance competes (an overdamped one is the extra state fitting noise).
    resonant = other is not None and other.params.get("compliance.damping", 0.0) < MAX_RESONANT_DAMPING
    beats_belt = not resonant or other is None or scr.gain_cv > other.gain_cv
    beyond_flicker = scr.detail.get("beyond_flicker", 0.0) >= MIN_BACKLASH_GAIN
    sane = cmp.t_stat > -MAX_BACKLASH_KSTEP_WORSE_T and 1.0 - cmp.improvement < MAX_BACKLASH_KSTEP_RATIO
    explains = scr.gain_cv >= MIN_BACKLASH_GAIN and scr.p_value <= MAX_SCREEN_P
    return explains and beats_belt and beyond_flicker and sane


__all__ = [
    "TORQUE_EFFECTS",
    "Judged",
    "finding",
    "judge_candidate",
    "look_alike_notes",
    "promote_angle_dependence",
    "rank",
    "reconsider_backlash",
    "kstep_ok",
    "refit_jointly",
    "refine_leaders",
    "refit_present_structure",
    "stiction_at_rest",
    "with_values",
]
