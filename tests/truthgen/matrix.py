"""The blind matrix: case specs (ids, split, settings), true-parameter draws, and generate_case."""

from __future__ import annotations

import math
import os
import zlib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np

from tests.truthgen.axis import TrueAxis
from tests.truthgen.controllers import (
    SIG_DITHER,
    SIG_FF,
    SIG_OL_A,
    SIG_OL_C,
    SIG_OL_FLAG,
    SIG_RDOT,
    SIG_REF,
    ControllerDesign,
    design_leadlag,
    design_open_loop,
    design_pdff,
    design_pid,
)
from tests.truthgen.encoder import step_for_counts
from tests.truthgen.excitation import (
    disturbance,
    empty_program,
    feed_forward,
    open_loop_chirp,
    open_loop_pulses,
    prbs,
    reference,
)
from tests.truthgen.presets import (
    AMPLIFIER_LIMIT_V,
    EFFECTS,
    GAIN_NM_PER_V,
    MOTOR_FRACTION,
    MOTOR_TO_LOAD_RATIO,
    preset,
)
from tests.truthgen.run import Log, simulate

MATRIX_SEED = int(os.environ.get("TRUTHGEN_MATRIX_SEED", "20250909"))  # another seed: a fresh blind set
DURATION_S = 30.0
RATES_HZ: tuple[int, ...] = (250, 500, 1000, 2000)
ENCODER_COUNTS: tuple[int, ...] = (500, 1000, 2048, 4000, 4096, 8192, 10000, 16384, 20000)
CONTROLLERS: tuple[str, ...] = ("pid", "leadlag", "pdff", "ol_steps", "ol_chirp")
CLOSED_LOOP: tuple[str, ...] = ("pid", "leadlag", "pdff")
PAIRS: tuple[tuple[str, str], ...] = (
    ("gravity", "delay"),
    ("offset", "ripple"),
    ("saturation", "stiction"),
    ("backlash", "gravity"),
    ("viscous_asymmetry", "compliance"),
    ("stiction", "gravity"),
    ("delay", "ripple"),
    ("coulomb_asymmetry", "gravity"),
    ("offset", "delay"),
    ("saturation", "gravity"),
    ("ripple", "compliance"),
    ("stiction", "delay"),
)
N_CLEAN = 50
N_PER_EFFECT = 11
N_PER_PAIR = 5
MAX_ATTEMPTS = 12
# Matrix seeds whose sets were generated and scored before the viscous asymmetry was drawn as a
# torque and redrawn until resolvable (session 13): they keep their old draw (b·[2, 3.5], most of
# it below the logs' resolution), so that their logs, the figures and regression tests cited on
# them, stay reproducible.
LEGACY_DRAW_SEEDS = frozenset({20250909, 777, 2411, 4242, 6006, 7171, 8080, 8181, 9191, 9393, 31337})
_DEBUG = False


@dataclass(frozen=True, slots=True)
class CaseSpec:
    """Settings of one log of the matrix (its true parameters are drawn from ``seed``).

    Attributes
    ----------
    id : str
        ``<group>-<nnn>``, group ``clean``, an effect, or ``a+b``.
    split : str
        ``"dev"`` or ``"heldout"``.
    group : str
        ``clean``, ``single`` or ``pair``.
    hidden : tuple of str
        Hidden catalogue effects.
    axis : str
        ``pan`` or ``tilt``.
    friction_law : str
        ``karnopp``, ``stribeck`` or ``lugre``.
    rate_hz : int
        Sample rate, Hz.
    latency_samples : int
        0 or 1.
    controller : str
        One of :data:`CONTROLLERS`.
    encoder_counts : int
        Counts per load revolution.
    encoder_mode : str
        ``round`` or ``truncate``.
    ripple_kind : str
        ``integer`` or ``non_integer`` (ripple cases only, else ``""``).
    """

    id: str
    split: str
    group: str
    hidden: tuple[str, ...]
    axis: str
    friction_law: str
    rate_hz: int
    latency_samples: int
    controller: str
    encoder_counts: int
    encoder_mode: str
    ripple_kind: str = ""


def _rng(*keys: int | str) -> np.random.Generator:
    ints = [k if isinstance(k, int) else zlib.crc32(k.encode()) for k in keys]
    return np.random.default_rng([MATRIX_SEED, *ints])


def _common(rng: np.random.Generator, hidden: tuple[str, ...]) -> dict[str, Any]:
    if "saturation" in hidden:  # the pan axis's larger inertia makes its controller demand more
        axis = "pan" if rng.random() < 0.75 else "tilt"
    elif "gravity" in hidden:  # a tilt axis carries the unbalance more often
        axis = "tilt" if rng.random() < 0.7 else "pan"
    else:
        axis = str(rng.choice(["pan", "tilt"]))
    ctrl_choices = ("pid", "leadlag") if "saturation" in hidden else CONTROLLERS
    weights = np.array([0.3, 0.2, 0.2, 0.15, 0.15][: len(ctrl_choices)])
    controller = str(rng.choice(ctrl_choices, p=weights / weights.sum()))
    return {
        "axis": axis,
        "rate_hz": int(rng.choice(RATES_HZ)),
        "controller": controller,
        "encoder_counts": int(rng.choice(ENCODER_COUNTS)),
        "encoder_mode": "truncate" if rng.random() < 0.3 else "round",
    }


@lru_cache(maxsize=1)
def build_matrix() -> tuple[CaseSpec, ...]:
    """All cases, in a fixed order; dev and heldout alternate inside every case type."""
    cases: list[CaseSpec] = []
    subtypes = [(law, lat) for law in ("karnopp", "lugre", "stribeck") for lat in (0, 1)]
    for j in range(N_CLEAN):
        law, lat = subtypes[(j // 2) % len(subtypes)]
        cid = f"clean-{j:03d}"
        c = _common(_rng("spec", cid), ())
        if j == 0:  # sample case: clean Karnopp at 1 kHz
            c.update(rate_hz=1000, controller="pid")
        if j == 2:  # sample case: clean at 500 Hz, latency 0
            c.update(rate_hz=500)
            lat = 0
        cases.append(
            CaseSpec(
                cid,
                "dev" if j % 2 == 0 else "heldout",
                "clean",
                (),
                friction_law=law,
                latency_samples=lat,
                **c,
            )
        )
    for e_idx, eff in enumerate(EFFECTS):
        for j in range(N_PER_EFFECT):
            cid = f"{eff}-{j:03d}"
            r = _rng("spec", cid)
            c = _common(r, (eff,))
            lat = int(r.random() < 0.3)
            rk = ""
            if eff == "ripple":
                rk = "non_integer" if (j // 2) % 2 == 0 else "integer"
            if j == e_idx % 2 and eff in ("gravity", "delay", "stiction", "ripple"):  # sample cases (dev)
                lat = 0
                if eff != "ripple":
                    c.update(controller="pid")
            cases.append(
                CaseSpec(
                    cid,
                    "dev" if (j + e_idx) % 2 == 0 else "heldout",
                    "single",
                    (eff,),
                    friction_law="karnopp",
                    latency_samples=lat,
                    ripple_kind=rk,
                    **c,
                )
            )
    for p_idx, pair in enumerate(PAIRS):
        for j in range(N_PER_PAIR):
            cid = f"{pair[0]}+{pair[1]}-{j:03d}"
            r = _rng("spec", cid)
            c = _common(r, pair)
            lat = int(r.random() < 0.3)
            rk = ("non_integer" if r.random() < 0.5 else "integer") if "ripple" in pair else ""
            cases.append(
                CaseSpec(
                    cid,
                    "dev" if (j + p_idx) % 2 == 0 else "heldout",
                    "pair",
                    pair,
                    friction_law="karnopp",
                    latency_samples=lat,
                    ripple_kind=rk,
                    **c,
                )
            )
    return tuple(cases)


@contextmanager
def seeded(seed: int) -> Iterator[None]:
    """The matrix of another seed (a fresh blind set) inside the block: ``build_matrix`` and
    ``generate_case`` read it; the cached matrix is cleared on the way in and out."""
    global MATRIX_SEED
    saved = MATRIX_SEED
    MATRIX_SEED = seed
    build_matrix.cache_clear()
    try:
        yield
    finally:
        MATRIX_SEED = saved
        build_matrix.cache_clear()


#: A small fixed sample (dev split): clean Karnopp 1 kHz, clean 500 Hz latency 0, gravity, delay,
#: stiction, ripple with a non-integer number of cycles per revolution.
SAMPLE_CASE_IDS: tuple[str, ...] = (
    "clean-000",
    "clean-002",
    "gravity-000",
    "delay-001",
    "stiction-001",
    "ripple-001",
)


def case_spec(case_id: str) -> CaseSpec:
    """The spec of ``case_id``."""
    for c in build_matrix():
        if c.id == case_id:
            return c
    raise KeyError(f"no case {case_id!r}")


def _logu(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_effect(
    eff: str, rng: np.random.Generator, base: dict[str, float], spec: CaseSpec
) -> dict[str, float]:
    """True parameters of a hidden effect (catalogue names, SI units)."""
    fc, b = base["coulomb.torque"], base["viscous.b"]
    u = rng.uniform
    if eff == "coulomb_asymmetry":
        k = u(0.5, 0.7) if rng.random() < 0.5 else u(1.4, 1.9)
        return {"coulomb_asymmetry.negative": fc * k}
    if eff == "viscous_asymmetry" and MATRIX_SEED in LEGACY_DRAW_SEEDS:
        return {"viscous_asymmetry.negative": b * u(2.0, 3.5)}
    if eff == "viscous_asymmetry":
        # Sized as a torque at 1 rad/s, 10–30 % of the Coulomb torque: the rig's own viscous
        # torque is about 1 % of Coulomb there, so a multiple of b (the old 2–3.5 b) was drawn
        # below every log's resolution (session 12: z 0.1–4 on all six held-out logs).
        return {"viscous_asymmetry.negative": b + fc * u(0.1, 0.3)}
    if eff == "offset":
        return {"offset.torque": float(rng.choice([-1.0, 1.0])) * u(0.012, 0.03)}
    if eff == "stiction":
        return {"stiction.static_torque": fc * u(1.5, 2.2), "stiction.velocity": u(0.02, 0.08)}
    if eff == "gravity":
        return {"gravity.torque": u(0.03, 0.08), "gravity.phase": u(-math.pi, math.pi)}
    if eff == "delay":
        return {"delay.seconds": u(max(0.003, 2.0 / spec.rate_hz), 0.020)}
    if eff == "saturation":
        return {"saturation.limit": u(2.0, 5.0)}
    if eff == "ripple":
        if spec.ripple_kind == "non_integer":
            n = float(rng.choice([MOTOR_TO_LOAD_RATIO, 2.0 * MOTOR_TO_LOAD_RATIO, 23.5]))
        else:
            n = float(rng.integers(8, 41))
        return {
            "ripple.amplitude": u(0.008, 0.025),
            "ripple.cycles_per_rev": n,
            "ripple.phase": u(-math.pi, math.pi),
        }
    if eff == "backlash":
        return {"backlash.width": u(0.006, 0.025)}
    if eff == "compliance":
        return {"compliance.frequency": u(8.0, 30.0), "compliance.damping": u(0.04, 0.2)}
    raise ValueError(f"unknown effect {eff!r}")


def draw_axis(spec: CaseSpec, rng: np.random.Generator) -> TrueAxis:
    """The true axis of ``spec``: the preset perturbed by [0.8, 1.25] per parameter, plus effects."""
    p0 = preset(spec.axis)
    params = {k: v * _logu(rng, 0.8, 1.25) for k, v in p0.base_params().items()}
    params["inertia.motor_fraction"] = MOTOR_FRACTION
    params["quantization.step"] = step_for_counts(spec.encoder_counts)
    for eff in spec.hidden:
        params.update(draw_effect(eff, rng, params, spec))
    friction: dict[str, float] = {}
    fc, j = params["coulomb.torque"], params["inertia.J"]
    if spec.friction_law == "stribeck":
        friction = {
            "static_torque": fc * rng.uniform(1.0, 1.05),
            "velocity": rng.uniform(0.02, 0.1),
            "exponent": float(rng.choice([1.0, 2.0])),
        }
    elif spec.friction_law == "lugre":
        z = rng.uniform(1e-4, 4e-4)
        s0 = fc / z
        zeta = rng.uniform(0.3, 0.7)
        friction = {
            "sigma0": s0,
            "sigma1": 2.0 * zeta * math.sqrt(s0 * j),
            "sigma2": params["viscous.b"],
            "presliding_rad": z,
            "bristle_damping_ratio": zeta,
            "static_torque": fc,
            "velocity": 0.05,
        }
    return TrueAxis(GAIN_NM_PER_V, params, list(spec.hidden), spec.friction_law, friction)


def _design(spec: CaseSpec, rng: np.random.Generator, axis: TrueAxis) -> ControllerDesign:
    p0 = preset(spec.axis)
    period = 1.0 / spec.rate_hz
    wc_hi = 30.0
    lag = axis.params.get("delay.seconds", 0.0) + (spec.latency_samples + 0.5) * period
    wc_hi = min(wc_hi, max(15.0, 0.45 / lag))
    if "compliance" in spec.hidden:
        wc_hi = min(wc_hi, max(12.0, 0.35 * 2.0 * math.pi * axis.params["compliance.frequency"]))
    wc_lo = 22.0 if "saturation" in spec.hidden else 15.0
    wc = rng.uniform(min(wc_lo, wc_hi - 1.0), wc_hi)
    if spec.controller == "pid":
        return design_pid(p0, wc, period)
    if spec.controller == "leadlag":
        return design_leadlag(p0, wc, period)
    if spec.controller == "pdff":
        return design_pdff(p0, wc, period)
    return design_open_loop(p0.range_rad)


def _program(spec: CaseSpec, rng: np.random.Generator, n: int) -> tuple[np.ndarray, dict[str, Any]]:
    p0 = preset(spec.axis)
    period = 1.0 / spec.rate_hz
    sig = empty_program(n)
    info: dict[str, Any] = {}
    if spec.controller in CLOSED_LOOP:
        sat = "saturation" in spec.hidden
        r, kinds = reference(
            rng,
            n,
            period,
            p0.range_rad,
            smooth=spec.controller == "pdff",
            step_speed=None if sat else rng.uniform(1.5, 4.0),
            step_weight=3 if sat else 2,
            hold_s=(0.3, 0.9) if sat else (0.8, 2.5),
            small_share=0.1 if sat else 0.35,
            sweep_top_hz=(3.0, 5.0) if sat else (1.5, 4.0),
            min_step=0.4 if sat else 0.0,
        )
        sig[SIG_REF] = r
        info["reference"] = kinds
        if spec.controller == "pdff":
            sig[SIG_RDOT], sig[SIG_FF] = feed_forward(r, period, p0)
    elif spec.controller == "ol_steps":
        sig[SIG_OL_A], sig[SIG_OL_FLAG], kinds = open_loop_pulses(rng, n, period, p0)
        info["pulses"] = kinds
    else:
        sig[SIG_OL_A], sig[SIG_OL_C], sig[SIG_OL_FLAG] = open_loop_chirp(rng, n, period, p0)
        info["chirp"] = True
    return sig, info


def check_log(log: Log, spec: CaseSpec, axis: TrueAxis) -> list[str]:
    """Reasons the log is not a good one (empty: it moves richly and stays sane)."""
    bad: list[str] = []
    R = preset(spec.axis).range_rad
    th, u = log.theta, log.u
    if not (np.all(np.isfinite(th)) and np.all(np.isfinite(u))):
        return ["not finite"]
    span = float(th.max() - th.min())
    if span < 0.3 * R:
        bad.append(f"span {span:.3f} rad")
    lim = 3.0 * R if spec.controller in CLOSED_LOOP else 6.0 * R + 2.0
    if float(np.abs(th).max()) > lim:
        bad.append(f"wandered to {float(np.abs(th).max()):.2f} rad")
    moving = float(np.mean(np.diff(log.theta_motor) != 0.0))
    if moving < 0.15:
        bad.append(f"moving {moving:.2f} of the time")
    dt = 1.0 / spec.rate_hz
    w = np.diff(log.theta_motor) / dt
    k = max(1, int(0.02 / dt))
    ws = np.convolve(w, np.ones(k) / k, mode="same")
    sgn = np.sign(ws[np.abs(ws) > 0.05])
    reversals = int(np.count_nonzero(np.diff(sgn) != 0))
    if reversals < 6:
        bad.append(f"{reversals} reversals")
    vmax = float(np.abs(ws).max())
    if vmax > 8.0:
        bad.append(f"speed {vmax:.1f} rad/s")
    if vmax < 0.3:
        bad.append(f"speed only {vmax:.2f} rad/s")
    pegged = float(np.mean(np.abs(u) >= AMPLIFIER_LIMIT_V - 1e-9))
    if pegged > 0.2:
        bad.append(f"command at the rail {pegged:.2f} of the time")
    if "saturation" in spec.hidden:
        over = float(np.mean(np.abs(u) > axis.params["saturation.limit"]))
        if over < 0.015:
            bad.append(f"command beyond the saturation limit only {over:.3f} of the time")
    return bad


def _unresolvable(log: Log, truth: Mapping[str, Any]) -> list[str]:
    """A single hidden viscous asymmetry the log cannot resolve (``bench/detectability.py``, which
    imports nothing of the workbench, rates it below its ``MIN_Z``): the case is drawn again, so
    that the effect is present in the log, not lost under its noise (legacy seeds excepted)."""
    if list(truth["hidden"]) != ["viscous_asymmetry"] or MATRIX_SEED in LEGACY_DRAW_SEEDS:
        return []
    from bench.detectability import MIN_Z, detectability

    r = detectability(truth, log.t, log.u, log.theta)
    z = float(r["value"])
    return [] if z >= MIN_Z else [f"viscous asymmetry at {z:.1f} standard errors (< {MIN_Z:g})"]


def generate_case(case_id: str, refine: float = 1.0) -> tuple[Log, dict[str, Any]]:
    """Simulate case ``case_id`` of the matrix.

    Parameters
    ----------
    case_id : str
        An id of :func:`build_matrix`.
    refine : float
        Divides the integration sub-step (1 for the matrix; 2 in the convergence test).

    Returns
    -------
    log : Log
        ``log.t`` (s), ``log.u`` (V), ``log.theta`` (rad): the CSV columns.
    truth : dict
        The truth record written beside the CSV (see the README).

    Raises
    ------
    RuntimeError
        When no attempt gives a log that passes :func:`check_log`.
    """
    spec = case_spec(case_id)
    n = int(round(DURATION_S * spec.rate_hz))
    period = 1.0 / spec.rate_hz
    problems: list[str] = []
    for attempt in range(MAX_ATTEMPTS):
        rng = _rng("case", case_id, attempt)
        if attempt == MAX_ATTEMPTS // 2 and spec.controller != "pid":
            # a program that will not behave with this controller: fall back to the PID
            spec = replace(spec, controller="pid")
        axis = draw_axis(spec, rng)
        design = _design(spec, rng, axis)
        sig, info = _program(spec, rng, n)
        noise_info: dict[str, float] = {
            "theta_std_rad": 0.0,
            "disturbance_rms_nm": 0.0,
            "disturbance_bandwidth_hz": 0.0,
            "dither_v": 0.0,
            "dither_hold_samples": 0,
        }
        if spec.controller in CLOSED_LOOP and rng.random() < 0.4:
            amp, hold = rng.uniform(0.05, 0.15), int(rng.choice([1, 2, 4]))
            sig[SIG_DITHER] = prbs(rng, n, amp, hold)
            noise_info.update(dither_v=amp, dither_hold_samples=hold)
        rms = 0.0 if rng.random() < 0.3 else rng.uniform(0.0, 3e-3)
        bw = rng.uniform(0.5, 5.0)
        dist = disturbance(rng, n, period, rms, bw)
        noise_info.update(disturbance_rms_nm=rms, disturbance_bandwidth_hz=bw if rms > 0 else 0.0)
        q = axis.params["quantization.step"]
        noise = None
        if rng.random() < 0.15:
            sd = rng.uniform(0.2, 0.6) * q
            noise = sd * rng.standard_normal(n)
            noise_info["theta_std_rad"] = sd
        if "saturation" in spec.hidden:
            # Place the limit under what this controller and program demand: the 99th percentile
            # of |u| of the same run with the nominal ±10 V amplifier.
            free = TrueAxis(
                axis.gain,
                {k: v for k, v in axis.params.items() if k != "saturation.limit"},
                [],
                axis.friction_law,
                axis.friction,
            )
            free.hidden = [e for e in axis.hidden if e != "saturation"]
            pre = simulate(
                free,
                design,
                sig,
                spec.rate_hz,
                latency_samples=spec.latency_samples,
                encoder_mode=spec.encoder_mode,
                noise=noise,
                dist=dist,
                refine=refine,
            )
            q99 = float(np.quantile(np.abs(pre.u), 0.99))
            if q99 < 2.2:
                problems = [f"demand 99th percentile {q99:.2f} V"]
                continue
            axis.params["saturation.limit"] = float(rng.uniform(2.0, min(5.0, q99)))
        log = simulate(
            axis,
            design,
            sig,
            spec.rate_hz,
            latency_samples=spec.latency_samples,
            encoder_mode=spec.encoder_mode,
            noise=noise,
            dist=dist,
            refine=refine,
        )
        problems = check_log(log, spec, axis)
        if _DEBUG:
            print(case_id, attempt, problems)
        if not problems:
            truth: dict[str, Any] = {
                "id": spec.id,
                "split": spec.split,
                "axis": spec.axis,
                "gain_nm_per_v": axis.gain,
                "sample_rate_hz": spec.rate_hz,
                "encoder_counts_per_rev": spec.encoder_counts,
                "encoder_mode": spec.encoder_mode,
                "latency_samples": spec.latency_samples,
                "controller": spec.controller,
                "friction_law": spec.friction_law,
                "hidden": list(spec.hidden),
                "params": dict(axis.params),
                "noise": noise_info,
                "friction": dict(axis.friction),
                "controller_params": design.describe,
                "program": info,
                "group": spec.group,
                "attempt": attempt,
                "duration_s": DURATION_S,
            }
            problems = _unresolvable(log, truth)
            if not problems:
                return log, truth
    raise RuntimeError(f"{case_id}: no good log after {MAX_ATTEMPTS} attempts ({'; '.join(problems)})")
