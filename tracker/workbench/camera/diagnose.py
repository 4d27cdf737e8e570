"""Which effect is the camera model missing? Each candidate judged on held-out data.

The camera's effects interact: with a hidden latency a closed-loop log's commands change every
few periods, so a free speed table fitted without the latency is garbage, and a latency alone
explains little while the table is linear. So each missing effect E (latency, speed_table,
acceleration, backlash) is judged twice, always on held-out data — refitted on one half of the
log (alternating blocks of ``max(BLOCK_S, 4 horizons)``) and its k-step error scored on the
other half, and vice versa:

* **needed**: the *full* model (the current one with every missing effect) against the full
  model without E — does anything else stand in for E?
* **alone**: the current model with E against the current model (the gain of the next step).

E is **significant** when it is needed (or, when the full model fits a half clearly worse
than the current one — it nests it, so that is a failed fit — when it helps alone):
the held-out error without it is at least ``MIN_GAIN``
higher in both halves *and* block by block (the log-ratio of each block's error, a one-sided
t-test over blocks, t < ``T_CRIT``), and the current model's error is above the quantization
floor (a model at the floor has nothing left to explain). Look-alikes (latency and an
acceleration limit both delay the response) are told apart by the needed test: the full model
keeps the one the data need. A free speed table has dozens of parameters: fitted on one half
it can only win on the other if the table really is not linear, so parsimony is the held-out
test itself. The ranking is by the needed gain; the verdict is the first significant
candidate, or none. Quantization is listed with the count found in the data and the error's
distance from its floor, never as significant: it changes no prediction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tracker.workbench.camera.fit import CameraFitResult, fit_camera
from tracker.workbench.camera.log import CameraLog
from tracker.workbench.camera.model import CAMERA_EFFECTS, EFFECT_TEXT, EXPERIMENTS, LOOK_ALIKES, CameraModel
from tracker.workbench.camera.predict import compare_camera, count_step_rad, horizon_rows, increment_errors

FloatArray = NDArray[np.float64]
BLOCK_S = 3.0
MIN_GAIN = 0.05
T_CRIT = -3.0
FLOOR_FACTOR = 1.3
FAILED_FIT = 1.25
JUDGED = ("latency", "speed_table", "acceleration", "backlash")


@dataclass(frozen=True, slots=True)
class CameraCandidate:
    """One effect the model lacks, added, refitted and judged."""

    effect: str
    significant: bool
    heldout_gain_percent: float
    half_gains_percent: tuple[float, float]
    block_t: float
    fit_percent: float
    params: dict[str, float]
    stderr: dict[str, float]
    evidence: str
    confused_with: tuple[str, ...]
    experiment: str
    model: CameraModel | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, object]:
        return {
            "effect": self.effect,
            "significant": self.significant,
            "heldout_gain_percent": self.heldout_gain_percent,
            "half_gains_percent": list(self.half_gains_percent),
            "block_t": self.block_t,
            "fit_percent": self.fit_percent,
            "params": self.params,
            "stderr": self.stderr,
            "evidence": self.evidence,
            "confused_with": list(self.confused_with),
            "experiment": self.experiment,
        }


@dataclass(frozen=True, slots=True)
class CameraDiagnosis:
    """The ranked candidates and the verdict."""

    fit_percent: float
    rms_deg: float
    verdict: str | None
    candidates: tuple[CameraCandidate, ...]
    notes: tuple[str, ...]
    model: CameraModel = field(repr=False)

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": "camera",
            "fit_percent": self.fit_percent,
            "rms_deg": self.rms_deg,
            "verdict": self.verdict,
            "candidates": [c.to_dict() for c in self.candidates],
            "notes": list(self.notes),
            "model": self.model.to_dict(),
        }


def heldout_halves(log: CameraLog, k: int) -> tuple[NDArray[np.bool_], NDArray[np.int64]]:
    """(mask of half A over predictions k..n-1, block index of each prediction)."""
    block_s = max(BLOCK_S, 4 * k * log.period_s)
    block = ((log.t_s[k:] - log.t_s[0]) // block_s).astype(np.int64)
    return (block % 2) == 0, block


@dataclass(frozen=True, slots=True)
class _Judged:
    half_rms: tuple[float, float]
    block_sse: dict[int, float]
    fits: tuple[CameraFitResult, CameraFitResult]


def _judge(
    log: CameraLog,
    model: CameraModel,
    k: int,
    half_a: NDArray[np.bool_],
    block: NDArray[np.int64],
    horizon_s: float | None,
    warm: bool = False,
) -> _Judged:
    """Fit on each half, score on the other: held-out RMS per half and SSE per block.

    ``warm``: ``model`` already holds values fitted on the whole log; each half starts from
    them (the searches of the starting values struggle with many effects on half a log)."""
    rms: list[float] = []
    sse: dict[int, float] = {}
    fits = []
    for train in (half_a, ~half_a):
        res = fit_camera(log, model, horizon_s=horizon_s, rows=train, start=not warm)
        fits.append(res)
        err = increment_errors(log, res.model, k)
        test = ~train
        rms.append(float(np.sqrt(np.mean(err[test] ** 2))))
        for b in np.unique(block[test]):
            sel = test & (block == b)
            sse[int(b)] = float(np.sum(err[sel] ** 2))
    return _Judged((rms[0], rms[1]), sse, (fits[0], fits[1]))


def _block_t(base: _Judged, cand: _Judged) -> float:
    """One-sided t statistic of the blocks' log error ratio (negative: the candidate is better)."""
    r = np.array(
        [math.log((cand.block_sse[b] + 1e-30) / (base.block_sse[b] + 1e-30)) for b in base.block_sse]
    )
    if r.size < 3:
        return 0.0
    sd = float(np.std(r, ddof=1))
    return float(np.mean(r) / (sd / math.sqrt(r.size))) if sd > 0 else (-math.inf if np.mean(r) < 0 else 0.0)


def _evidence(effect: str, model: CameraModel, log: CameraLog) -> str:
    """The effect's fitted values in words."""
    if effect == "latency":
        lat = model.latency_s
        return (
            f"commands act {1e3 * lat:.0f} ms after they are logged "
            f"({lat / log.period_s:.1f} command periods of {1e3 * log.period_s:.1f} ms)"
        )
    if effect == "acceleration":
        a = model.accel_rad_s2
        vmax = float(np.max(np.abs(model.speeds_rad_s(log.step))))
        return (
            f"the speed follows commands at {math.degrees(a):.0f}°/s² "
            f"(the fastest speed used, {math.degrees(vmax):.1f}°/s, takes {vmax / a:.2f} s to reach)"
        )
    if effect == "backlash":
        return f"the angle waits for {math.degrees(model.backlash_rad):.2f}° of play after each reversal"
    if effect == "speed_table":
        return _table_words(model, log)
    return EFFECT_TEXT[effect]


def _table_words(model: CameraModel, log: CameraLog) -> str:
    used = sorted({int(abs(s)) for s in log.step if s != 0})
    lo, hi = used[0], used[-1]
    pos, neg = model.table_rad_s(1), model.table_rad_s(-1)
    both = 0.5 * (pos + neg)
    steps = np.array(used)
    line = float(np.sum(both[steps - 1] * steps) / np.sum(steps**2))  # best linear map through 0
    dev = float(np.max(np.abs(both[steps - 1] / (line * steps) - 1.0)))
    asym = float(np.median(neg[steps - 1] / pos[steps - 1]) - 1.0)
    words = (
        f"step {hi} runs {both[hi - 1] / both[lo - 1]:.1f}× as fast as step {lo} (a linear map: "
        f"{hi / lo:.1f}×); the table departs from the best linear map by up to {100 * dev:.0f} %"
    )
    if abs(asym) >= 0.02:
        words += f"; the negative direction is {100 * abs(asym):.0f} % {'faster' if asym > 0 else 'slower'}"
    return words


def _gains(base: _Judged, cand: _Judged) -> tuple[tuple[float, float], float]:
    """Held-out gain (%) of ``cand`` over ``base`` per half, and the blocks' t statistic."""
    gains = tuple(
        100.0 * (1.0 - c / b) if b > 0 else 0.0 for c, b in zip(cand.half_rms, base.half_rms, strict=True)
    )
    return (gains[0], gains[1]), _block_t(base, cand)


def _candidate(
    log: CameraLog,
    model: CameraModel,
    effect: str,
    needed: tuple[tuple[float, float], float],
    alone: tuple[tuple[float, float], float],
    horizon_s: float | None,
    base_fit: float,
) -> CameraCandidate:
    (g_need, t_need), (g_alone, t_alone) = needed, alone
    significant = min(g_need) >= 100 * MIN_GAIN and t_need < T_CRIT
    full = fit_camera(log, model.with_effect(effect), horizon_s=horizon_s)
    own = {n: v for n, v in full.model.params().items() if n.startswith(_prefix(effect))}
    mean_need = float(np.mean(g_need))
    return CameraCandidate(
        effect=effect,
        significant=significant,
        heldout_gain_percent=mean_need,
        half_gains_percent=g_need,
        block_t=t_need,
        fit_percent=full.fit_percent_increment,
        params=own,
        stderr={n: v for n, v in full.stderr.items() if n in own},
        evidence=f"{_evidence(effect, full.model, log)}; "
        f"without it the full model's held-out k-step error is "
        f"{mean_need:+.0f} % higher than with it (halves {g_need[0]:+.0f} / {g_need[1]:+.0f} %, blocks "
        f"t = {-t_need:.1f}); added alone: {-float(np.mean(g_alone)):+.0f} % (t = {t_alone:.1f}), fit "
        f"{base_fit:.2f} → {full.fit_percent_increment:.2f} %",
        confused_with=LOOK_ALIKES[effect],
        experiment=EXPERIMENTS[effect],
        model=full.model,
    )


def _without(model: CameraModel, effect: str) -> CameraModel:
    """``model`` without ``effect``; without its table, the linear map that fits the table best."""
    if effect == "speed_table":
        steps = np.arange(1, model.n_steps + 1, dtype=float)
        both = 0.5 * (model.table_rad_s(1) + model.table_rad_s(-1))
        per_step = float(np.sum(both * steps) / np.sum(steps**2))
        return model.without_effect(effect).with_params({"speed.per_step": per_step})
    return model.without_effect(effect)


def _prefix(effect: str) -> str:
    return {
        "latency": "latency.",
        "speed_table": "speed_table.",
        "acceleration": "acceleration.",
        "backlash": "backlash.",
    }.get(effect, effect + ".")


def diagnose_camera(log: CameraLog, model: CameraModel, horizon_s: float | None = None) -> CameraDiagnosis:
    """Rank the camera effects ``model`` lacks on ``log`` (see the module docstring)."""
    k = horizon_rows(log, horizon_s)
    if log.max_step > model.n_steps:
        model = CameraModel.base(log.max_step, model.effects)
    half_a, block = heldout_halves(log, k)
    current = fit_camera(log, model, horizon_s=horizon_s)
    cmp = compare_camera(log, current.model, horizon_s)
    base = _judge(log, model, k, half_a, block, horizon_s)
    q = count_step_rad(log)
    floor_rad = q / math.sqrt(6.0)
    at_floor = q > 0 and cmp.rms_deg <= FLOOR_FACTOR * math.degrees(floor_rad)
    notes: list[str] = []
    cands: list[CameraCandidate] = []
    missing = [e for e in JUDGED if not model.has(e)]
    full_model = model
    for e in missing:
        full_model = full_model.with_effect(e)
    full_fit = fit_camera(log, full_model, horizon_s=horizon_s).model if len(missing) > 1 else full_model
    full = _judge(log, full_fit, k, half_a, block, horizon_s, warm=True) if len(missing) > 1 else None
    if full is not None and any(
        f > FAILED_FIT * b for f, b in zip(full.half_rms, base.half_rms, strict=True)
    ):
        # the full model nests the current one: much worse on held-out data (more than a free
        # table's overfitting) means its fit failed (many effects at once on half a log), so it
        # cannot be the reference
        notes.append(
            "the model with every effect did not fit both halves of the log: each effect is "
            "judged added alone"
        )
        full = None
    for effect in missing:
        with_it = _judge(log, model.with_effect(effect), k, half_a, block, horizon_s)
        alone = _gains(base, with_it)
        if full is None:
            needed = alone
        else:
            without = _judge(log, _without(full_fit, effect), k, half_a, block, horizon_s, warm=True)
            needed = _gains(without, full)
        c = _candidate(log, model, effect, needed, alone, horizon_s, current.fit_percent_increment)
        if at_floor and c.significant:
            c = _replace_significant(c, False)
        cands.append(c)
    cands.sort(key=lambda c: (not c.significant, -c.heldout_gain_percent))
    if at_floor:
        notes.append(
            f"the k-step error ({cmp.rms_deg:.4f}°) is at the quantization floor "
            f"({math.degrees(floor_rad):.4f}° for a count of {math.degrees(q):.4f}°): nothing is missing"
        )
    if not model.has("quantization"):
        ratio = cmp.rms_deg / math.degrees(floor_rad) if floor_rad > 0 else math.inf
        cands.append(
            CameraCandidate(
                effect="quantization",
                significant=False,
                heldout_gain_percent=0.0,
                half_gains_percent=(0.0, 0.0),
                block_t=0.0,
                fit_percent=current.fit_percent_increment,
                params={"quantization.step": q},
                stderr={},
                evidence=(
                    f"the angle comes in counts of {math.degrees(q):.4f}°; "
                    f"the k-step error is {ratio:.1f}× its "
                    "floor (a sensor effect: it changes no prediction)"
                )
                if q > 0
                else "the angle shows no counts (continuous, or finer than its noise)",
                confused_with=(),
                experiment="",
                model=current.model.with_effect("quantization").with_params(
                    {"quantization.step": min(q, 0.1)}
                ),
            )
        )
    sig = [c for c in cands if c.significant]
    verdict = sig[0].effect if sig else None
    if len(sig) > 1:
        notes.append(
            "also significant: "
            + ", ".join(c.effect for c in sig[1:])
            + f" — add {sig[0].effect} and diagnose again"
        )
    for c in sig:
        alike = [o.effect for o in sig if o.effect in c.confused_with]
        if alike and c is sig[0]:
            notes.append(f"{c.effect} and {', '.join(alike)} look alike: {c.experiment}")
    worst = max(cmp.regimes.items(), key=lambda kv: kv[1].concentration)
    if worst[1].concentration > 1.5:
        notes.append(
            f"the current model's error concentrates at {worst[0].replace('_', ' ')} windows "
            f"({worst[1].concentration:.1f}× their share of time)"
        )
    return CameraDiagnosis(
        fit_percent=current.fit_percent_increment,
        rms_deg=cmp.rms_deg,
        verdict=verdict,
        candidates=tuple(cands),
        notes=tuple(notes),
        model=current.model,
    )


def _replace_significant(c: CameraCandidate, value: bool) -> CameraCandidate:
    from dataclasses import replace

    return replace(c, significant=value)


__all__ = ["CAMERA_EFFECTS", "CameraCandidate", "CameraDiagnosis", "diagnose_camera"]
