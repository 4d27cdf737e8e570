"""Which physical effect is the model missing? Rank every effect of the catalogue, give a verdict.

Two stages (see docs/workbench.md, "Diagnosis"):

1. Screening by inverse dynamics (:mod:`tracker.workbench.diagnose.screening`, ``effect_search``):
   for each missing effect, the torque balance is refitted with its terms added (searching its
   nonlinear parameter) and scored on held-out time blocks; an F-test on the effective sample
   size of the time-correlated residual says whether the gain is beyond chance.
2. Judgement by simulation (:mod:`tracker.workbench.diagnose.kstep`): each candidate model, with the
   screening's parameters, predicts k steps ahead from the measured states; a paired test over
   blocks of windows against the current structure (refitted) says whether it predicts better.
   The verdict candidate is then refitted on the k-step error for its final parameters.

An effect is *significant* only when both stages agree and the gains are of a size that
matters (not merely detectable). A model that is already right gets no verdict.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

from tracker.errors import JobCancelled
from tracker.plant.effects import OPTIONAL_EFFECTS
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.breakaway import analyse_breakaway
from tracker.workbench.diagnose.effect_search import screen_missing_effects
from tracker.workbench.diagnose.evidence import EvidenceContext, describe, experiment_for, notes_for
from tracker.workbench.diagnose.judgement import (
    TORQUE_EFFECTS,
    Judged,
    finding,
    judge_candidate,
    look_alike_notes,
    negligible,
    promote_angle_dependence,
    rank,
    reconsider_backlash,
    refine_leaders,
    refit_present_structure,
    with_values,
)
from tracker.workbench.diagnose.kstep import KStepJudge, KStepScore
from tracker.workbench.diagnose.refitted_base import judge_against_refitted_base
from tracker.workbench.diagnose.rests import analyse_rests, slow_residual_nm
from tracker.workbench.diagnose.screening import (
    Structure,
    TorqueDesign,
    load_fall,
    model_params,
    sliding_coulomb,
)
from tracker.workbench.diagnose.sensor_floor import sensor_torque_sse
from tracker.workbench.diagnose.slow_disturbance import JUDGED_EFFECTS, SlowDisturbance, within_disturbance
from tracker.workbench.diagnose.startlags import analyse_start_lags
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.idim import Signals, encoder_timing_s, prepare_signals

FAR_OFF_RATIO = 2.0  # the current parameters are "far off" when a base refit halves the error
# The finding of a candidate significant only with a latency the encoder does not resolve.
UNRESOLVED_LATENCY = "only with an unresolved latency"


@dataclass(frozen=True, slots=True)
class Candidate:
    """One effect the model might be missing.

    ``fit_percent`` is the k-step fit the model reaches with it added and refitted; ``params``
    its parameters (``"<effect>.<param>"``, SI) and ``stderr`` their standard errors;
    ``confused_with`` effects that explain the same residual; ``experiment`` what to run to
    confirm it or tell it from those.
    """

    effect: str
    fit_percent: float
    params: Mapping[str, float]
    stderr: Mapping[str, float]
    significant: bool
    evidence: str
    confused_with: tuple[str, ...] = ()
    experiment: str | None = None
    screen_gain: float = 0.0
    kstep_gain: float = 0.0
    # "computational latency", "within a latency", "significant but small", "only with an
    # unresolved latency", or None
    finding: str | None = None
    model: AxisModel | None = field(default=None, repr=False, compare=False)  # the model with it added

    def to_dict(self) -> dict[str, object]:
        return {
            "effect": self.effect,
            "fit_percent": self.fit_percent,
            "params": dict(self.params),
            "stderr": dict(self.stderr),
            "significant": self.significant,
            "evidence": self.evidence,
            "confused_with": list(self.confused_with),
            "experiment": self.experiment,
            "screen_gain": self.screen_gain,
            "kstep_gain": self.kstep_gain,
            "finding": self.finding,
        }


@dataclass(frozen=True, slots=True)
class Diagnosis:
    """The current model's fit, the verdict (or None) and every candidate, best first."""

    fit_percent: float
    verdict: str | None
    candidates: tuple[Candidate, ...]
    notes: tuple[str, ...] = ()
    elapsed_s: float = 0.0
    baseline_params: Mapping[str, float] = field(default_factory=dict)
    # The fit with the base parameters refitted, when the current ones are far off the data
    # (the candidates are then judged against that refit).
    refit_fit_percent: float | None = None

    def to_dict(self) -> dict[str, object]:
        """The CLI contract: fit_percent, verdict, candidates (best first), plus notes."""
        return {
            "fit_percent": self.fit_percent,
            "verdict": self.verdict,
            "candidates": [c.to_dict() for c in self.candidates],
            "notes": list(self.notes),
            "elapsed_s": self.elapsed_s,
            "refit_fit_percent": self.refit_fit_percent,
        }

    def candidate(self, effect: str) -> Candidate:
        """The candidate for ``effect`` (KeyError if the model already has it)."""
        for c in self.candidates:
            if c.effect == effect:
                return c
        raise KeyError(effect)


def diagnose(
    meas: Measurement,
    model: AxisModel,
    horizon_s: float | None = None,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    refit_present: bool = True,
) -> Diagnosis:
    """Rank the effects ``model`` lacks by how much of ``meas`` they explain; give a verdict.

    Parameters
    ----------
    meas : measured log (t s, u V, θ rad).
    model : the current model (base plus the effects it already has).
    horizon_s : k-step prediction horizon (default 0.03 s, as ``compare``).
    progress : called with the fraction done (0..1).
    cancel : polled; returning True raises :class:`JobCancelled`.
    refit_present : when ``model`` already has effects, refit its parameters (base and
        effects) by the k-step error before judging the candidates against it.

    Returns
    -------
    Diagnosis
    """
    t0 = time.perf_counter()

    def step(frac: float) -> None:
        if cancel is not None and cancel():
            raise JobCancelled("diagnosis cancelled")
        if progress is not None:
            progress(frac)

    step(0.0)
    sig = prepare_signals(meas)
    design = TorqueDesign(sig, model.gain_nm_per_v, model.params["inertia.motor_fraction"], load_fall(model))
    base = Structure.of(model)
    base_reg = design.fit(base)
    base_values, _ = model_params(model, base, base_reg)
    step(0.1)
    screens = screen_missing_effects(design, model, base, base_reg, cancel)
    step(0.5)

    judge = KStepJudge(meas, sig, horizon_s)
    current = judge.score(model)
    refit = with_values(model, base_values)
    refit_score = judge.score(refit)
    base_model, base_score = (refit, refit_score) if refit_score.sse < current.sse else (model, current)
    two_mass = model.has("backlash") or model.has("compliance")
    # A second round on a rigid model: the model already has an effect, fitted (by the user)
    # together with the base, and its parameters trade with the base's (a bias with gravity's
    # constant part, a delay with the inertia). Judge the candidates against the present structure
    # at the judge's own optimum, or a candidate is credited with what a refit of what is already
    # there would gain (and built on values that absorbed part of it). A belt or a dead band keeps
    # its own path (torque effects refitted with the friction, judged on halves): refitted by the
    # judge, the load's hidden state fits so closely that a torque of a fraction of a mN·m passed.
    present = bool(model.effects) and not two_mass
    if present and refit_present:
        base_model, base_score = refit_present_structure(judge, base_model, base_score, cancel)
    at_rest = sig.stuck[judge.starts]
    rest_err = float(base_score.window_sse[at_rest].sum() / max(base_score.sse, 1e-300))
    # The rests judged against the Coulomb torque of the moving data (the torque regression):
    # a model fitted to the whole run may have absorbed part of a missing break-away.
    moving_coulomb = float(base_values.get("coulomb.torque", base_model.params["coulomb.torque"]))
    breakaway = analyse_breakaway(meas, base_model)
    # A second round times the starts from rest against the rigid body and the torques of
    # position of the moving data too (the torque regression), as it judges them over its
    # Coulomb: the present structure, fitted and refitted to the whole run without a missing
    # stiction, has traded its inertia, viscous friction and gravity against the late starts,
    # and those set when each start is due (9191 held-out stiction+gravity-000: J 1.5x, b 0,
    # gravity 13 % high; the starts then told no level from none, and rejected the true one).
    lags_model = with_values(base_model, base_values) if present and refit_present else base_model
    ctx = EvidenceContext(
        sig,
        design,
        base_reg,
        breakaway,
        model,
        (rest_err, float(at_rest.mean())),
        analyse_rests(sig, base_reg, base_model, moving_coulomb),
        analyse_start_lags(sig, lags_model, moving_coulomb, slow_residual_nm(sig, base_reg)),
        # what a measured break-away is judged over (two more low-passes: only when there is one)
        sliding_coulomb(design, model, base_reg)
        if breakaway is not None and breakaway.static_excess_se > 0
        else None,
    )
    # A torque effect's share of the residual is judged beyond the encoder's own (rigid models).
    # A first round (and its look again with a computational latency added) counts the inertial
    # torque the regression's noise-shrunken inertia leaves as the encoder's too, against the
    # inertia the simulation judges by; a user's second round keeps the regression's inertia.
    if two_mass:
        sensor_sse = 0.0
    elif present and refit_present:
        sensor_sse = sensor_torque_sse(sig, base_reg)
    else:
        sensor_sse = sensor_torque_sse(sig, base_reg, float(base_model.params["inertia.J"]))
    rows = [
        judge_candidate(
            scr,
            screens,
            judge,
            base_model,
            base_score,
            ctx,
            two_mass,
            cancel,
            present=present,
            sensor_sse=sensor_sse,
            second_round=present and refit_present,
        )
        for scr in screens.values()
    ]
    step(0.7)
    reconsider_backlash(rows, screens, ctx)
    rank(rows, judge, ctx, screens)
    refine_leaders(rows, judge, base_score, ctx, step, cancel)
    reconsider_backlash(rows, screens, ctx)  # a belt its refit by simulation rejected
    rank(rows, judge, ctx, screens)
    if promote_angle_dependence(rows, judge, base_score, ctx):
        rank(rows, judge, ctx, screens)
    refitted = present and refit_present
    if (
        not refitted
        and not two_mass
        and judge_against_refitted_base(rows, judge, base_model, base_score, cancel)
    ):
        rank(rows, judge, ctx, screens)
    if _judge_by_disturbance(rows, meas, base_model, sig, judge.k * judge.dt):
        rank(rows, judge, ctx, screens)

    significant = [r.effect for r in rows if r.significant]
    candidates = [_candidate(r, ctx, significant) for r in rows]
    if "quantization" in OPTIONAL_EFFECTS and not model.has("quantization"):
        candidates.append(_quantization_candidate(ctx, current.fit_percent, base_score))
    verdict = candidates[0].effect if candidates and candidates[0].significant else None
    told = look_alike_notes(rows)
    notes = notes_for(candidates, ctx, verdict, compared=bool(told)) + told
    small = [(r.effect, negligible(r.effect, r.model, ctx)) for r in rows if r.passed and not r.significant]
    notes += tuple(f"{effect} is detectable but small: {why}" for effect, why in small if why)
    notes += tuple(
        f"{r.effect} is detectable but small: {r.within_disturbance}" for r in rows if r.within_disturbance
    )
    notes += tuple(f"{r.effect} is within a latency: {r.within_latency}" for r in rows if r.within_latency)
    far_off = refit_score.sse < current.sse and current.sse > FAR_OFF_RATIO * refit_score.sse
    if far_off:
        notes = (
            "the current model's parameters are far from this data: with its base parameters refitted by "
            f"inverse dynamics the fit is {refit_score.fit_percent:.3f} % "
            f"instead of {current.fit_percent:.3f} %; "
            "candidates are judged against that refit (run `tracker model fit`)",
        ) + notes
    latency = next((c for c in candidates if c.finding == "computational latency"), None)
    if latency is not None and latency.model is not None:
        # A one-sample latency is part of the loop, not a missing effect of the axis; judge the
        # rest against a model that has it, or every other candidate competes to explain it.
        inner = diagnose(
            meas,
            latency.model,
            horizon_s,
            lambda f: step(0.8 + 0.2 * f),
            cancel,
            refit_present=bool(model.effects),
        )
        found = [c for c in inner.candidates if c.significant]
        others = [c for c in inner.candidates if not c.significant]
        notes = tuple(n for n in notes if "computational latency" in n) + inner.notes
        timing_s = encoder_timing_s(sig.theta_raw_rad, sig.dt_s)
        if latency.params.get("delay.seconds", 0.0) < timing_s:
            # The encoder does not resolve the latency (its counts come further apart than the
            # latency while moving), so the log cannot say whether the command acts one sample
            # late or not: a verdict must hold either way, significant without the latency too.
            kept = {c.effect for c in candidates if c.significant}
            dropped = [c for c in found if c.effect not in kept]
            found = [c for c in found if c.effect in kept]
            unnamed = [replace(c, significant=False, finding=UNRESOLVED_LATENCY) for c in dropped]
            others = unnamed + others
            notes += tuple(_only_with_latency_note(c.effect, latency, timing_s, sig.dt_s) for c in dropped)
        candidates = [*found, latency, *others]
        verdict = found[0].effect if found else None
        base_model = latency.model
    step(1.0)
    elapsed = time.perf_counter() - t0
    return Diagnosis(
        current.fit_percent,
        verdict,
        tuple(candidates),
        notes,
        elapsed,
        dict(base_model.params),
        refit_score.fit_percent if far_off else None,
    )


def _judge_by_disturbance(
    rows: list[Judged], meas: Measurement, model: AxisModel, sig: Signals, horizon_s: float
) -> bool:
    """Set aside (in place) significant torque effects no larger than what the log's own slow
    load disturbance makes of a torque of their shape (:mod:`.slow_disturbance`); True when any
    was. The disturbance is read only when such a candidate is significant."""
    judged = [r for r in rows if r.significant and r.effect in JUDGED_EFFECTS]
    if not judged:
        return False
    slow = SlowDisturbance.read(meas, model, sig, horizon_s)
    changed = False
    for r in judged:
        why = within_disturbance(r.effect, r.model, model, sig, slow)
        if why is not None:
            r.significant, r.within_disturbance, changed = False, why, True
    return changed


def _candidate(r: Judged, ctx: EvidenceContext, significant: list[str]) -> Candidate:
    """The public card of a judged candidate."""
    params = {k: v for k, v in r.model.params.items() if k.split(".")[0] == r.effect}
    # Standard errors from the stage that produced the values: the torque regression for
    # torque effects, the k-step refit for the others (none when neither estimated them).
    source = r.stderr or (dict(r.screen.stderr) if r.effect in TORQUE_EFFECTS else {})
    return Candidate(
        effect=r.effect,
        fit_percent=r.score.fit_percent,
        params=params,
        stderr={k: v for k, v in source.items() if k.split(".")[0] == r.effect},
        significant=r.significant,
        evidence=describe(r.effect, r.screen, r.cmp, ctx, r.model.params)
        + (f"; {r.established}" if r.established else "")
        + (f"; {ctx.start_lags.describe()}" if ctx.start_lags and r.effect in ("stiction", "delay") else ""),
        confused_with=ctx.confusions(r.effect, significant),
        experiment=experiment_for(r.effect),
        screen_gain=r.screen.gain_cv,
        kstep_gain=r.cmp.improvement,
        finding=finding(r, ctx),
        model=r.model,
    )


def _only_with_latency_note(effect: str, latency: Candidate, timing_s: float, dt_s: float) -> str:
    """Why ``effect``, significant only once the latency is in the model, is not named."""
    d = latency.params.get("delay.seconds", 0.0)
    return (
        f"{effect} is significant only with the computational latency ({1e3 * d:.2f} ms = "
        f"{d / dt_s:.2f} samples) in the model, and the encoder does not resolve that latency (its "
        f"counts come {1e3 * timing_s:.1f} ms apart while moving): not named, as the log cannot "
        "say whether the latency is there"
    )


def _quantization_candidate(ctx: EvidenceContext, fit: float, base_score: KStepScore) -> Candidate:
    q = ctx.sig.encoder_step_rad
    rms = float((base_score.end_error**2).mean() ** 0.5)
    floor = q / 12**0.5
    if q > 0:
        ev = (
            f"encoder step {q:.3g} rad in the data; k-step error RMS {rms:.3g} rad is "
            f"{rms / floor:.1f}× the quantization floor step/√12 = {floor:.3g} rad "
            "(a sensor effect: it changes no prediction, so adding it cannot improve the fit)"
        )
    else:
        ev = "no encoder step found in the data (unquantized or noisy sensor)"
    return Candidate("quantization", fit, {"quantization.step": q} if q > 0 else {}, {}, False, ev, (), None)


__all__ = ["Candidate", "Diagnosis", "diagnose", "with_values"]
