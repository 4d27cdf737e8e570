"""The diagnosis in words: evidence with numbers, look-alike effects and the experiments that split them."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from scipy import signal

from tracker.plant.effects import CATALOGUE, Effect, generic_effects, get_effect, is_generic
from tracker.plant.effects import ripple as ripple_effect
from tracker.plant.effects import saturation as saturation_effect
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.breakaway import BreakAway
from tracker.workbench.diagnose.kstep import Comparison
from tracker.workbench.diagnose.rests import RestHolds
from tracker.workbench.diagnose.screening import Screen, TorqueDesign
from tracker.workbench.diagnose.startlags import StartLags
from tracker.workbench.fit import generic
from tracker.workbench.measurements.idim import Regression, Signals, encoder_timing_s

if TYPE_CHECKING:
    from tracker.workbench.diagnose.diagnose import Candidate

T = TypeVar("T")


class _FromCatalogue(Mapping[str, T]):
    """A live mapping effect name -> one field of its catalogue entry (effects where it is set)."""

    def __init__(self, field: Callable[[Effect], T | None]) -> None:
        self._field = field

    def _items(self) -> dict[str, T]:
        return {n: v for n, e in CATALOGUE.items() if (v := self._field(e)) is not None}

    def __getitem__(self, name: str) -> T:
        return self._items()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items())

    def __len__(self) -> int:
        return len(self._items())


# Effects that explain the same residual on ordinary closed-loop data, and the experiment that
# confirms each or tells it from those: both live in the effect's own file (Effect.look_alikes,
# Effect.experiment); these are views of the catalogue.
LOOK_ALIKES: Mapping[str, tuple[str, ...]] = _FromCatalogue(
    lambda e: e.look_alikes if e.kind not in ("base", "sensor") else None
)
EXPERIMENTS: Mapping[str, str] = _FromCatalogue(lambda e: e.experiment)


@dataclass(frozen=True, slots=True)
class EvidenceContext:
    """What every evidence sentence draws on: the prepared run and the baseline regression."""

    sig: Signals
    design: TorqueDesign
    base_reg: Regression
    breakaway: BreakAway | None
    model: AxisModel
    rest_share: tuple[float, float] = (0.0, 0.0)  # (share of k-step error, share of windows) from rest
    rests: RestHolds | None = None  # rests that held a torque beyond Coulomb (open-loop steps)
    start_lags: StartLags | None = None  # start times from rest: a constant lag or a break-away level
    # the sliding Coulomb torque of the moving data and its standard error (N·m), at the
    # low-pass that determines it best (:func:`...screening.sliding_coulomb`); None: the base regression's
    sliding_coulomb: tuple[float, float] | None = None

    def confusions(self, effect: str, significant: Sequence[str]) -> tuple[str, ...]:
        """Look-alike effects of ``effect``: its own, then generic effects that name it as theirs
        (a site's effect can name a built-in); those also significant first."""
        alike = list(LOOK_ALIKES.get(effect, ()))
        naming = [n for n in generic_effects() if effect in LOOK_ALIKES.get(n, ())]
        alike += [n for n in naming if n not in (*alike, effect)]
        return tuple(sorted(alike, key=lambda e: e not in significant))

    def concentration(self, mask_full: np.ndarray) -> tuple[float, float]:
        """(share of baseline residual energy, share of time) where ``mask_full`` holds."""
        r = self.base_reg.residual
        m = mask_full[self.sig.use]
        tot = float(r @ r) or 1.0
        return float(np.sum(r[m] ** 2) / tot), float(np.mean(m))


def _mnm(x: float) -> str:
    """A torque for the evidence text (N·m; N on a linear axis)."""
    return f"{x:+.3g} N·m"


def _direction_means(ctx: EvidenceContext) -> tuple[float, float, float]:
    r = ctx.base_reg.residual
    om = ctx.sig.omega_rad_s[ctx.sig.use]
    pos, neg = r[om > 0], r[om < 0]
    se = float(np.std(r)) * math.sqrt(2.0 / max(ctx.base_reg.n_eff, 2.0))
    return float(pos.mean()) if pos.size else 0.0, float(neg.mean()) if neg.size else 0.0, se


def _resonance(ctx: EvidenceContext) -> tuple[float, float]:
    """(peak frequency Hz, peak/median ratio) of the baseline residual torque spectrum."""
    sig = ctx.sig
    step = int(np.median(np.diff(sig.use))) or 1
    r = np.zeros(sig.t_s.size)
    r[sig.use] = ctx.base_reg.residual
    x = r[::step]
    fs = 1.0 / (sig.dt_s * step)
    f, p = signal.welch(x, fs=fs, nperseg=min(512, x.size))
    band = (f > 1.0) & (f < min(2 * sig.cutoff_hz, 0.45 * fs))
    if not band.any():
        return 0.0, 0.0
    i = int(np.argmax(p[band]))
    return float(f[band][i]), float(p[band][i] / (np.median(p[band]) or 1.0))


def ripple_not_repeating(cycles_per_rev: float, ctx: EvidenceContext) -> str | None:
    """Why a ripple of ``cycles_per_rev`` is not seen to repeat over the run's angles, or None
    (:func:`tracker.plant.effects.ripple.not_repeating` on the baseline's residual torque).

    With a belt or a dead band in the model the test does not apply: the ripple acts on the load
    and reaches the motor's residual torque through the transmission's dynamics, which change its
    amplitude with the speed (and so with where the axis moves); the simulation judges it there.
    """
    if ctx.model.has("compliance") or ctx.model.has("backlash"):
        return None
    sig = ctx.sig
    return ripple_effect.not_repeating(sig.theta_rad[sig.use], ctx.base_reg.residual, cycles_per_rev)


def saturation_not_where_clipped(limit_v: float, ctx: EvidenceContext) -> str | None:
    """Why a clip at ``limit_v`` is no saturation, or None
    (:func:`tracker.plant.effects.saturation.not_where_clipped` on the baseline's residual torque)."""
    return saturation_effect.not_where_clipped(*ctx.concentration(np.abs(ctx.sig.u_v) > limit_v))


def describe(
    effect: str, scr: Screen, cmp: Comparison, ctx: EvidenceContext, params: Mapping[str, float]
) -> str:
    """One sentence of evidence with numbers for ``effect`` (``params``: the candidate's final values)."""
    p, d = params, scr.detail
    sig = ctx.sig
    tail = (
        f"; explains {100 * scr.gain_cv:.0f} % of the held-out residual torque, "
        f"k-step error {-100 * cmp.improvement:+.0f} % (t = {cmp.t_stat:.1f})"
    )
    if effect in ("offset", "coulomb_asymmetry"):
        mp, mn, se = _direction_means(ctx)
        same = (mp > 0) == (mn > 0)
        kind = "the same sign both ways: a bias torque" if same else "opposite signs: direction-dependent"
        head = (
            f"residual torque averages {_mnm(mp)} moving positive and {_mnm(mn)} moving negative "
            f"(± {se:.2g}), {kind}"
        )
        if effect == "offset":
            head += f"; bias {_mnm(p['offset.torque'])}"
        else:
            head += (
                f"; Coulomb {p['coulomb.torque']:.3g} N·m positive, "
                f"{p['coulomb_asymmetry.negative']:.3g} N·m negative"
            )
        return head + tail
    if effect == "viscous_asymmetry":
        return (
            f"residual torque grows with speed differently by direction: viscous "
            f"{p['viscous.b']:.3g} N·m·s/rad positive, {p['viscous_asymmetry.negative']:.3g} negative" + tail
        )
    if effect == "gravity":
        th = sig.theta_rad[sig.use]
        g = p["gravity.torque"] * np.sin(th + p["gravity.phase"])
        r = ctx.base_reg.residual
        rr = float(np.corrcoef(r, g)[0, 1]) if np.std(g) > 0 and np.std(r) > 0 else 0.0
        return (
            f"residual torque follows sin(θ {p['gravity.phase']:+.2f} rad) (r = {rr:.2f}), "
            f"amplitude {p['gravity.torque']:.3g} N·m over a {np.ptp(th):.2f} rad range" + tail
        )
    if effect == "ripple":
        why = ripple_not_repeating(p["ripple.cycles_per_rev"], ctx)
        return (
            f"residual is periodic in θ with {d.get('cycles_per_rev', 0):.2f} cycles per revolution "
            f"(periodogram peak {d.get('peak_ratio', 0):.0f}× the median), amplitude "
            f"{p['ripple.amplitude']:.3g} N·m" + (f"; {why}" if why else "") + tail
        )
    if effect == "stiction":
        e, tfrac = ctx.rest_share
        ba = ctx.breakaway
        extra = ""
        if ba is not None:
            extra = (
                f"; break-away from rest needs {_mnm(ba.static_excess_nm)} ± {ba.static_excess_se:.2g} "
                f"over Coulomb in {ba.count} creeping starts"
            )
            one_sided = ba.one_sided()
            extra += f" ({one_sided})" if one_sided else ""
        return (
            f"error concentrates at starts from rest ({100 * e:.0f} % of the prediction error in the "
            f"{100 * tfrac:.0f} % of windows that start at rest){extra}; break-away "
            f"{p['stiction.static_torque']:.3g} N·m, Stribeck velocity {p['stiction.velocity']:.3g} rad/s"
            + tail
        )
    if effect == "delay":
        ba = ctx.breakaway
        extra = ""
        if ba is not None and math.isfinite(ba.delay_se):
            extra = f"; break-away lags the command by {1e3 * ba.delay_s:.1f} ± {1e3 * ba.delay_se:.1f} ms"
        samples = p["delay.seconds"] / sig.dt_s
        if samples < 0.5:
            meaning = " (under half a sample period: the sampling convention, not a drive delay)"
        elif samples < 1.5:
            meaning = (
                " (one sample: the command logged at row i acts from row i + 1 — the controller's "
                "computational latency or the logging order, not a delay of the drive)"
            )
        else:
            meaning = ""
        timing_s = encoder_timing_s(sig.theta_raw_rad, sig.dt_s)
        if samples >= 0.5 and p["delay.seconds"] < timing_s:
            meaning += (
                f" (within the encoder's timing of {1e3 * timing_s:.1f} ms: the typical time between "
                "its counts while moving, so not resolved as a drive delay)"
            )
        return (
            f"input–residual alignment is best with the command delayed by {1e3 * p['delay.seconds']:.2f} ms "
            f"= {samples:.2f} samples of {1e3 * sig.dt_s:.3g} ms{meaning}{extra}" + tail
        )
    if effect == "saturation":
        lim = p["saturation.limit"]
        e, tfrac = ctx.concentration(np.abs(sig.u_v) > lim)
        why = saturation_not_where_clipped(lim, ctx)
        return (
            f"error appears when |u| > {lim:.2f} V ({100 * e:.0f} % of the residual torque in "
            f"{100 * tfrac:.0f} % of the time)" + (f"; {why}" if why else "") + tail
        )
    if effect == "backlash":
        rev = np.abs(sig.alpha_rad_s2) < 0.1 * float(np.std(sig.alpha_rad_s2))
        e, tfrac = ctx.concentration(rev)
        return (
            f"the encoder moves through a dead band of {p['backlash.width']:.3g} rad when the torque "
            f"reverses, with reduced inertia ({100 * e:.0f} % of the residual torque in {100 * tfrac:.0f} % "
            "of the time, near acceleration reversals); beyond a count's flicker at reversals it explains "
            f"{100 * d.get('beyond_flicker', 0.0):.0f} % of the residual torque" + tail
        )
    if effect == "compliance":
        f, ratio = _resonance(ctx)
        # With the encoder on the motor a log fixes the load's swing against a held motor,
        # √(k/J_load) = f·√(share): the two-mass frequency f follows from the motor's share of J,
        # which the model holds (outside generator seed 19: shares of 0.26-0.30 read as f 30-45 %
        # high, the load's swing within 3 %).
        share = float(p.get("inertia.motor_fraction", 0.15))
        f_load = p["compliance.frequency"] * math.sqrt(share)
        return (
            f"residual torque spectrum peaks at {f:.1f} Hz ({ratio:.0f}× the median); belt resonance "
            f"{p['compliance.frequency']:.1f} Hz, damping {p['compliance.damping']:.2f} (the load swings "
            f"against a held motor at {f_load:.1f} Hz, which the log fixes; the resonance assumes the "
            f"motor holds {100 * share:.0f} % of the inertia)" + tail
        )
    return generic_evidence(effect, ctx, params) + tail


def generic_evidence(effect: str, ctx: EvidenceContext, params: Mapping[str, float]) -> str:
    """Evidence for an effect without sentences of its own: its signature, how well its torque
    follows the residual torque, and its own words (``Effect.evidence``)."""
    eff = get_effect(effect)
    if not is_generic(effect):
        return "no evidence computed"
    sig = ctx.sig
    th = sig.theta_rad[sig.use]
    r = ctx.base_reg.residual
    own = generic.point(eff, params)
    tau = sig.lowpass(generic.torque_at_rest(eff, own, sig.theta_rad))[sig.use]
    rr = float(np.corrcoef(r, tau)[0, 1]) if np.std(tau) > 0 and np.std(r) > 0 else 0.0
    span = float(np.ptp(th))
    head = f"{eff.signature} (r = {rr:.2f} between its torque and the residual; θ spans {span:.2f} rad)"
    words = ""
    if callable(eff.evidence):
        words = eff.evidence(own, th, r)
    elif eff.evidence:
        short = {k.partition(".")[2]: v for k, v in own.items()}
        words = eff.evidence.format(**short, range_rad=span)
    return head + (f"; {words}" if words else "")


def experiment_for(effect: str) -> str | None:
    """The experiment that confirms ``effect`` or tells it from its look-alikes."""
    e = CATALOGUE.get(effect)
    return e.experiment if e is not None else None


def notes_for(
    candidates: Sequence[Candidate], ctx: EvidenceContext, verdict: str | None, compared: bool = False
) -> tuple[str, ...]:
    """Ambiguities between significant candidates and the experiments that would resolve them.

    ``compared``: a held-out comparison of gravity with a bias torque has its own notes
    (:func:`tracker.workbench.diagnose.judgement.look_alike_notes`), which replace the general one."""
    sig_names = [c.effect for c in candidates if c.significant]
    by = {c.effect: c for c in candidates}
    notes: list[str] = []
    latency = by.get("delay")
    if latency is not None and latency.finding == "computational latency":
        d = latency.params.get("delay.seconds", 0.0)
        notes.append(
            f"the command acts one sample after the row it is logged on ({1e3 * d:.2f} ms = "
            f"{d / ctx.sig.dt_s:.2f} samples): the controller's computational latency (its output is "
            "applied at the next tick), not a delay of the drive. Predictions need it: add it with "
            f"`--effects delay --set delay.seconds={d:.3g}`, or log each command on the row where it "
            "is applied"
        )
    if verdict is None:
        notes.append(
            "no effect explains a significant share of the residual: the model structure is "
            "adequate for this data (refit its parameters with `tracker model fit` if needed)"
        )
    if "offset" in by and "coulomb_asymmetry" in by and ({"offset", "coulomb_asymmetry"} & set(sig_names)):
        mp, mn, _ = _direction_means(ctx)
        notes.append(
            "offset and coulomb_asymmetry explain the same residual: on a rigid axis with Coulomb friction a "
            "bias torque o is direction-dependent friction with Fc⁺ = Fc + o, Fc⁻ = Fc − o "
            f"(residual torque {_mnm(mp)} moving positive, {_mnm(mn)} negative). "
            "Named here as a bias torque. "
            "To tell them apart: " + EXPERIMENTS["offset"]
        )
    if "viscous_asymmetry" in sig_names and ({"offset", "coulomb_asymmetry"} & set(sig_names)):
        notes.append(
            "direction-dependent viscous friction competes with a bias torque: the one with the larger "
            "k-step gain is ranked first; diagnose again after adding it to see whether the other remains"
        )
    if {"stiction", "delay"} & set(sig_names):
        ba = ctx.breakaway
        if ba is not None:
            notes.append(
                f"stiction and delay both live at reversals; {ba.count} creeping starts from rest give a "
                "break-away excess "
                f"of {_mnm(ba.static_excess_nm)} ± {ba.static_excess_se:.2g} at zero command rate (stiction) "
                f"and a lag of {1e3 * ba.delay_s:.1f} ± {1e3 * ba.delay_se:.1f} ms (delay). To be sure: "
                + EXPERIMENTS["stiction"]
            )
        else:
            notes.append(
                "stiction and delay both live at reversals and this run has too few starts from rest to "
                "separate them: " + EXPERIMENTS["stiction"]
            )
    if {"backlash", "compliance"} <= set(sig_names):
        notes.append("backlash and compliance both hide a load state; " + EXPERIMENTS["compliance"])
    if {"gravity", "offset"} <= set(sig_names) and float(np.ptp(ctx.sig.theta_rad)) < 1.5 and not compared:
        notes.append(
            f"gravity and a bias torque look alike over the {np.ptp(ctx.sig.theta_rad):.2f} rad this run "
            "covers; " + EXPERIMENTS["gravity"]
        )
    bias = by.get("offset")
    span = float(np.ptp(ctx.sig.theta_rad))
    if ctx.model.has("gravity") and bias is not None and not bias.significant and span < 1.5:
        # Over a short travel gravity is a level and a slope; a bias (or a Coulomb asymmetry)
        # on top of it only shows in the torque's curvature, which such a run barely resolves.
        b = bias.params.get("offset.torque", 0.0)
        se = bias.stderr.get("offset.torque", math.inf)
        notes.append(
            f"a bias torque on top of gravity (or direction-dependent Coulomb friction) is not resolved "
            f"over the {span:.2f} rad this run covers: fitted together with gravity it comes out at "
            f"{b:+.3g} ± {se:.2g} N·m, and gravity's phase takes up what the torque's curvature cannot "
            "tell apart; " + EXPERIMENTS["gravity"]
        )
    if verdict is not None and is_generic(verdict):
        alike = [e for e in ctx.confusions(verdict, sig_names) if e in sig_names]
        experiment = experiment_for(verdict)
        if alike and experiment:
            notes.append(
                f"{verdict} and {', '.join(alike)} explain much the same residual over the "
                f"{np.ptp(ctx.sig.theta_rad):.2f} rad this run covers; to tell them apart: {experiment}"
            )
    others = [e for e in sig_names if e != verdict]
    if verdict is not None and others:
        notes.append(f"also significant: {', '.join(others)}; add {verdict}, refit, and diagnose again")
    return tuple(notes)


__all__ = [
    "EXPERIMENTS",
    "LOOK_ALIKES",
    "EvidenceContext",
    "describe",
    "experiment_for",
    "generic_evidence",
    "notes_for",
]
