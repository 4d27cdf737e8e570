"""Which physical effect is the model missing? Rank every effect of the catalogue, give a verdict.

Two stages (see docs/workbench.md, "Diagnosis"):

1. Screening by inverse dynamics (:mod:`tracker.workbench.screening`, ``effect_search``):
   for each missing effect, the torque balance is refitted with its terms added (searching its
   nonlinear parameter) and scored on held-out time blocks; an F-test on the effective sample
   size of the time-correlated residual says whether the gain is beyond chance.
2. Judgement by simulation (:mod:`tracker.workbench.kstep`): each candidate model, with the
   screening's parameters, predicts k steps ahead from the measured states; a paired test over
   blocks of windows against the current structure (refitted) says whether it predicts better.
   The verdict candidate is then refitted on the k-step error for its final parameters.

An effect is *significant* only when both stages agree and the gains are of a size that
matters (not merely detectable). A model that is already right gets no verdict.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from tracker.errors import JobCancelled
from tracker.plant.effects import OPTIONAL_EFFECTS
from tracker.plant.model import AxisModel
from tracker.workbench.breakaway import analyse_breakaway
from tracker.workbench.data import Measurement
from tracker.workbench.effect_search import screen_missing_effects
from tracker.workbench.evidence import EvidenceContext, describe, experiment_for, notes_for
from tracker.workbench.idim import prepare_signals
from tracker.workbench.kstep import Comparison, HeldOutSearch, KStepJudge, KStepScore, held_out_search, refine
from tracker.workbench.screening import Screen, Structure, TorqueDesign, model_params

# A candidate must explain this share of the held-out residual torque (screening) ...
MIN_SCREEN_GAIN = 0.08
MAX_SCREEN_P = 1e-3
MAX_SCREEN_P_JUDGED = 0.05
# ... and cut the k-step prediction error by this share, consistently over blocks of windows.
MIN_KSTEP_GAIN = 0.05
MIN_KSTEP_ROBUST = 0.025
# Stiction is judged on its break-away excess when the moving data cannot see it.
MIN_BREAKAWAY_T = 4.0
REFINE_TOP = 2
MIN_BACKLASH_GAIN = 0.15
FAR_OFF_RATIO = 2.0  # the current parameters are "far off" when a base refit halves the error
MIN_BACKLASH_SIGNIFICANT_COUNTS = 8
MIN_BACKLASH_KSTEP = -2.0  # k-step error may grow (unobservable gap state) but not explode
MIN_DELAY_SAMPLES = 0.5
MIN_HELD_OUT_GAIN = 0.05
STICTION_RATIOS = (1.1, 1.25, 1.4, 1.6, 1.8, 2.0, 2.4)  # break-away / Coulomb tried by simulation
STRIBECK_VELOCITIES = (0.02, 0.05, 0.1)  # rad/s
TORQUE_EFFECTS = ("offset", "coulomb_asymmetry", "viscous_asymmetry", "gravity", "ripple")
# Torque-type effects keep their inverse-dynamics parameters (a direct regression on the torque
# is more accurate than a k-step refit); these act through the simulation and are refitted.
REFINED_BY_SIMULATION = ("stiction", "delay", "saturation", "compliance")


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

    def to_dict(self) -> dict[str, object]:
        """The CLI contract: fit_percent, verdict, candidates (best first), plus notes."""
        return {
            "fit_percent": self.fit_percent,
            "verdict": self.verdict,
            "candidates": [c.to_dict() for c in self.candidates],
            "notes": list(self.notes),
            "elapsed_s": self.elapsed_s,
        }

    def candidate(self, effect: str) -> Candidate:
        """The candidate for ``effect`` (KeyError if the model already has it)."""
        for c in self.candidates:
            if c.effect == effect:
                return c
        raise KeyError(effect)


def with_values(model: AxisModel, values: Mapping[str, float], add: str | None = None) -> AxisModel:
    """``model`` (plus effect ``add``) with ``values`` set, keeping every other value.

    (``AxisModel.with_effect`` would reset an existing asymmetry to symmetric.)
    """
    effects = (*model.effects, add) if add and not model.has(add) else model.effects
    keep = {k: v for k, v in model.params.items()}
    keep.update({k: v for k, v in values.items() if k.split(".")[0] in (*effects, "inertia", "viscous", "coulomb")})
    return AxisModel.create(model.gain_nm_per_v, {}, effects, keep)


def _effect_only(scr: Screen) -> Screen:
    """``scr`` with only the new effect's own parameters (the base model keeps its values)."""
    own = {k: v for k, v in scr.params.items() if k.split(".")[0] == scr.effect}
    return Screen(scr.effect, scr.structure, scr.regression, own, scr.stderr, scr.gain_cv, scr.p_value,
                  scr.folds_improve, scr.detail)


def _candidate_model(model: AxisModel, scr: Screen, ctx: EvidenceContext) -> AxisModel:
    values = dict(scr.params)
    if scr.effect == "stiction" and ctx.breakaway is not None and ctx.breakaway.static_t > MIN_BREAKAWAY_T:
        fc = values.get("coulomb.torque", model.params["coulomb.torque"])
        values["stiction.static_torque"] = max(values["stiction.static_torque"], fc + ctx.breakaway.static_excess_nm)
    return with_values(model, values, add=scr.effect)


def diagnose(
    meas: Measurement,
    model: AxisModel,
    horizon_s: float | None = None,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> Diagnosis:
    """Rank the effects ``model`` lacks by how much of ``meas`` they explain; give a verdict.

    Parameters
    ----------
    meas : measured log (t s, u V, θ rad).
    model : the current model (base plus the effects it already has).
    horizon_s : k-step prediction horizon (default 0.05 s, as ``compare``).
    progress : called with the fraction done (0..1).
    cancel : polled; returning True raises :class:`JobCancelled`.

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
    design = TorqueDesign(sig, model.gain_nm_per_v, model.params["inertia.motor_fraction"])
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
    at_rest = sig.stuck[judge.starts]
    rest_err = float(base_score.window_sse[at_rest].sum() / max(base_score.sse, 1e-300))
    ctx = EvidenceContext(sig, design, base_reg, analyse_breakaway(meas, base_model), model,
                          (rest_err, float(at_rest.mean())))

    rows = []
    two_mass = model.has("backlash") or model.has("compliance")
    for effect, scr in screens.items():
        cand_model = _candidate_model(base_model, scr, ctx)
        score = judge.score(cand_model)
        # Another missing effect can bias the regression's J, b, Fc (a delay shrinks the apparent
        # inertia): also try the effect alone on the base model's values, keep the better.
        alone = _candidate_model(base_model, _effect_only(scr), ctx)
        alone_score = judge.score(alone)
        if alone_score.sse < score.sse:
            cand_model, score = alone, alone_score
        cmp = judge.compare(base_score, score)
        # Torque effects must pass a strict F-test; the others must also win the k-step judgement
        # by a margin, so a looser one suffices (another missing effect left in the residual
        # shrinks its effective sample size).
        max_p = MAX_SCREEN_P if effect in TORQUE_EFFECTS else MAX_SCREEN_P_JUDGED
        screen_ok = scr.gain_cv >= MIN_SCREEN_GAIN and scr.p_value <= max_p and scr.folds_improve
        if effect == "stiction":
            # Moving data barely sees static friction (the axis leaves the Stribeck zone in a few
            # ms): search the break-away torque by simulation, chosen and judged on halves.
            search = _stiction_search(judge, base_model, base_score, cand_model)
            if search.held_out_gain > score_gain(cmp):
                cand_model, score = search.best, judge.score(search.best)
                cmp = judge.compare(base_score, score)
            held = min(search.gains) >= MIN_HELD_OUT_GAIN
            screen_ok = screen_ok or held or (ctx.breakaway is not None and ctx.breakaway.static_t > MIN_BREAKAWAY_T)
        sig_ok = screen_ok and _kstep_ok(effect, cmp)
        if effect == "backlash":
            sig_ok = _backlash_significant(scr, screens, cmp, sig.encoder_step_rad)
        elif not screen_ok and two_mass and effect in TORQUE_EFFECTS and cmp.improvement > 0:
            # With a belt or dead band in the model the torque regression is swamped by the rough
            # load reconstruction: refit the effect with the friction by simulation and judge it
            # on held-out halves of the k-step error.
            names = [k for k in cand_model.params if k.split(".")[0] in (effect, "viscous", "coulomb")]
            cand_model, _ = refine(judge, cand_model, names, max_evals=20, cancel=cancel)
            score = judge.score(cand_model)
            cmp = judge.compare(base_score, score)
            gains = judge.half_gains(base_score, score)
            sig_ok = min(gains) >= MIN_HELD_OUT_GAIN and _kstep_ok(effect, cmp)
        sig_ok = sig_ok and _physical(effect, cand_model, sig.dt_s)
        rows.append([effect, scr, cand_model, score, cmp, sig_ok, screen_ok])
    step(0.7)
    # Best first: significant ones, then the rest.
    rows.sort(key=_rank_key)
    # Ties between equivalent effects (a bias torque and direction-dependent Coulomb friction are
    # the same equation while moving): prefer the bias torque, the simpler physical story.
    _prefer_offset(rows)

    # Refit by simulation the leading candidates the screening supports: the verdict's final
    # parameters, and a second chance for hidden-state effects whose screening parameters
    # (inertia split, damping) are too rough for the k-step judgement.
    sim_stderr: dict[str, dict[str, float]] = {}
    hopeful = [r for r in rows if r[6] and r[4].improvement > 0 and r[0] in REFINED_BY_SIMULATION][:REFINE_TOP]
    for i, r in enumerate(hopeful):
        step(0.7 + 0.1 * i)
        refined, se = refine(judge, r[2], cancel=cancel)
        score = judge.score(refined)
        if score.sse < r[3].sse:
            cmp = judge.compare(base_score, score)
            r[2], r[3], r[4] = refined, score, cmp
            sim_stderr[r[0]] = se
            r[5] = (_kstep_ok(r[0], cmp) if r[0] != "backlash" else r[5]) and _physical(r[0], refined, sig.dt_s)
    rows.sort(key=_rank_key)
    _prefer_offset(rows)

    candidates = []
    for effect, scr, cand_model, score, cmp, sig_ok, _ in rows:
        params = {k: v for k, v in cand_model.params.items() if k.split(".")[0] == effect}
        # Standard errors from the stage that produced the values: the torque regression for
        # torque effects, the k-step refit for the others (none when neither estimated them).
        source = sim_stderr.get(effect, scr.stderr if effect in TORQUE_EFFECTS else {})
        stderr = {k: v for k, v in source.items() if k.split(".")[0] == effect}
        candidates.append(
            Candidate(
                effect=effect,
                fit_percent=score.fit_percent,
                params=params,
                stderr=stderr,
                significant=sig_ok,
                evidence=describe(effect, scr, cmp, ctx, cand_model.params),
                confused_with=ctx.confusions(effect, [r[0] for r in rows if r[5]]),
                experiment=experiment_for(effect),
                screen_gain=scr.gain_cv,
                kstep_gain=cmp.improvement,
                model=cand_model,
            )
        )
    if "quantization" in OPTIONAL_EFFECTS and not model.has("quantization"):
        candidates.append(_quantization_candidate(ctx, current.fit_percent, judge, base_score))
    verdict = candidates[0].effect if candidates and candidates[0].significant else None
    notes = notes_for(candidates, ctx, verdict)
    if base_model is not model and current.sse > FAR_OFF_RATIO * refit_score.sse:
        notes = (f"the current model's parameters are far from this data: with its base parameters refitted by "
                 f"inverse dynamics the fit is {refit_score.fit_percent:.3f} % instead of {current.fit_percent:.3f} %; "
                 "candidates are judged against that refit (run `tracker model fit`)",) + notes
    step(1.0)
    return Diagnosis(current.fit_percent, verdict, tuple(candidates), notes, time.perf_counter() - t0,
                     dict(base_model.params))


def score_gain(cmp: Comparison) -> float:
    return cmp.improvement


def _stiction_search(judge: KStepJudge, base: AxisModel, base_score: KStepScore, cand: AxisModel) -> HeldOutSearch:
    fc = cand.params["coulomb.torque"]
    grid = []
    for ratio in STICTION_RATIOS:
        for vs in STRIBECK_VELOCITIES:
            grid.append(with_values(base, {"stiction.static_torque": fc * ratio, "stiction.velocity": vs},
                                    add="stiction"))
    return held_out_search(judge, base_score, grid)


def _physical(effect: str, model: AxisModel, dt_s: float) -> bool:
    """False for values that are no physical effect: a delay below half a sample period is the
    sampling convention (when in the period the encoder is read), not a transport delay."""
    if effect == "delay":
        return model.params["delay.seconds"] >= MIN_DELAY_SAMPLES * dt_s
    return True


def _kstep_ok(effect: str, cmp: Comparison) -> bool:
    """The simulation agrees with the screening.

    Torque effects are measured best by the torque regression (a small viscous asymmetry
    barely moves a 30 ms prediction): the simulation must only agree in direction. Effects
    that act through the command or a hidden state are where inverse dynamics can be fooled
    (a clip level or a belt fitted to noise), so they must win by a margin.
    """
    if effect in TORQUE_EFFECTS:
        return cmp.improvement > 0.0 and cmp.robust_improvement > 0.0
    return cmp.improvement >= MIN_KSTEP_GAIN and cmp.robust_improvement >= MIN_KSTEP_ROBUST


def _rank_key(row: list[object]) -> tuple[bool, float]:
    """Significant first, then by the mean of held-out screening gain and k-step gain."""
    scr, cmp = row[1], row[4]
    return (not row[5], -0.5 * (scr.gain_cv + cmp.improvement))  # type: ignore[attr-defined]


def _backlash_significant(scr: Screen, screens: Mapping[str, Screen], cmp: Comparison, step_rad: float) -> bool:
    """Backlash by screening alone, with a stricter bar.

    Where the load sits in the dead band is not observable over a short prediction window (a
    load without friction coasts in the gap), so the k-step judgement cannot confirm backlash
    even for the true model. The screening reconstructs the load through the whole run instead;
    it must explain a large share of the held-out torque, and more than a belt would; its width
    must exceed a few encoder counts (below that it is quantization at reversals), and the
    simulation must not be made much worse by it.
    """
    other = screens.get("compliance")
    beats_belt = other is None or scr.gain_cv > other.gain_cv
    wide = scr.params.get("backlash.width", 0.0) >= MIN_BACKLASH_SIGNIFICANT_COUNTS * max(step_rad, 1e-12)
    sane = cmp.improvement > MIN_BACKLASH_KSTEP
    return scr.gain_cv >= MIN_BACKLASH_GAIN and scr.p_value <= MAX_SCREEN_P and beats_belt and wide and sane


def _prefer_offset(rows: list[list[object]]) -> None:
    names = [r[0] for r in rows]
    if "offset" in names and "coulomb_asymmetry" in names:
        i, j = names.index("coulomb_asymmetry"), names.index("offset")
        if i < j and rows[i][5] == rows[j][5]:
            gi, gj = rows[i][4].improvement, rows[j][4].improvement  # type: ignore[attr-defined]
            if gj >= gi - 0.02 * max(abs(gi), 1e-9) - 0.01:
                rows[i], rows[j] = rows[j], rows[i]


def _quantization_candidate(ctx: EvidenceContext, fit: float, judge: KStepJudge, base_score: object) -> Candidate:
    q = ctx.sig.encoder_step_rad
    rms = float((base_score.end_error ** 2).mean() ** 0.5)  # type: ignore[attr-defined]
    floor = q / 12**0.5
    if q > 0:
        ev = (f"encoder step {q:.3g} rad in the data; k-step error RMS {rms:.3g} rad is "
              f"{rms / floor:.1f}× the quantization floor step/√12 = {floor:.3g} rad "
              "(a sensor effect: it changes no prediction, so adding it cannot improve the fit)")
    else:
        ev = "no encoder step found in the data (unquantized or noisy sensor)"
    return Candidate("quantization", fit, {"quantization.step": q} if q > 0 else {}, {}, False, ev, (),
                     None)


__all__ = ["Candidate", "Diagnosis", "diagnose", "with_values"]
