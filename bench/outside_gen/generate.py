"""One seeded log on disk: NAME.csv (README's format) and NAME.truth.json (every parameter, the
hidden effect in the catalogue's names, and its size against the log's own floor)."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from bench.outside_gen.loop import Run, write_csv
from bench.outside_gen.scenario import (
    Scenario,
    draw_base,
    simulate,
    torque_floor_nm,
    with_effect,
    with_saturation,
)

# the catalogue's parameters of each effect (README table)
EFFECT_PARAMS = {
    "offset": ("offset.torque",),
    "coulomb_asymmetry": ("coulomb_asymmetry.negative",),
    "viscous_asymmetry": ("viscous_asymmetry.negative",),
    "stiction": ("stiction.static_torque",),
    "gravity": ("gravity.torque",),
    "delay": ("delay.seconds",),
    "saturation": ("saturation.limit",),
    "ripple": ("ripple.amplitude", "ripple.cycles_per_rev"),
    "backlash": ("backlash.width",),
    "compliance": ("compliance.frequency", "compliance.damping"),
}


def build_once(name: str, seed: int, effect: str | None, duration_s: float = 20.0) -> tuple[Scenario, Run]:
    sc = draw_base(name, seed, effect, duration_s)
    rng = np.random.default_rng(seed + 31337)
    if effect == "saturation":
        sc = with_saturation(sc, simulate(sc), rng)
    elif effect is not None:
        sc = with_effect(sc, rng)
    return sc, simulate(sc)


def clearly_present(size: dict[str, float]) -> bool:
    """The run shows its hidden effect above its own floor: a torque (or the torque a delay or a
    clip takes away) ≥ 3·σ_d and ≥ 1.5 counts' torque τ_q, a dead band ≥ 6 counts, a belt's twist
    ≥ 3 counts RMS."""
    if "effect_torque_nm" in size and (size["over_disturbance"] < 3 or size["over_count_torque"] < 1.5):
        return False
    return size.get("width_counts", 6.0) >= 6 and size.get("twist_rms_counts", 3.0) >= 3


def build(
    name: str, seed: int, effect: str | None, duration_s: float = 20.0, tries: int = 6
) -> tuple[Scenario, Run]:
    """A log whose hidden effect is clearly present: redrawn (seed + 7919·k) until it is. A draw
    whose plant diverges under the fixed-step integrator (a stiff or unstable loop) is no log:
    it is redrawn too."""
    built: tuple[Scenario, Run] | None = None
    for k in range(tries):
        try:
            built = build_once(name, seed + 7919 * k, effect, duration_s)
        except FloatingPointError:
            continue
        if effect is None or clearly_present(size_of_effect(*built)):
            break
    if built is None:
        raise FloatingPointError(f"{name} (seed {seed}): the plant diverged in all {tries} draws")
    return built


def size_of_effect(sc: Scenario, run: Run) -> dict[str, float]:
    """How large the hidden effect is on this run, in units of the log's own floor."""
    pl, m = sc.plant, sc.plant.motor
    step = sc.encoder.step_rad(m.gear_ratio)
    w = np.gradient(run.load_true_rad, run.t_s)
    out = {
        "disturbance_nm": sc.disturbance_nm,
        "count_torque_nm": sc.count_torque_nm(),
        "encoder_step_rad": step,
        "torque_floor_nm": torque_floor_nm(sc),
    }
    fm, fl = pl.friction_motor, pl.friction_load
    torque: float | None = None
    if sc.effect == "offset":
        torque = abs(pl.bias_nm)
    elif sc.effect == "coulomb_asymmetry":
        torque = abs(fm.fc_neg_nm + fl.fc_neg_nm - fm.fc_pos_nm - fl.fc_pos_nm)
    elif sc.effect == "viscous_asymmetry":
        neg = w[w < 0]
        torque = float((fm.b_neg_nms - fm.b_pos_nms) * np.sqrt(np.mean(neg**2))) if neg.size else 0.0
    elif sc.effect == "stiction":
        torque = fm.fs_nm + fl.fs_nm - fm.fc_pos_nm - fl.fc_pos_nm
    elif sc.effect == "gravity":
        torque = pl.gravity_nm
    elif sc.effect == "ripple":
        torque = pl.cog_nm
    elif sc.effect == "delay":
        lag = max(1, round(sc.delay_s * sc.rate_hz))
        torque = float(m.gain_nm_per_v * np.sqrt(np.mean((run.u_v[lag:] - run.u_v[:-lag]) ** 2)))
        out["delay_samples"] = sc.delay_s * sc.rate_hz
    elif sc.effect == "saturation":
        lim = m.amp_rail_v / m.amp_gain_v_per_v
        torque = float(m.gain_nm_per_v * np.sqrt(np.mean((run.u_v - np.clip(run.u_v, -lim, lim)) ** 2)))
        out["clipped_fraction"] = float(np.mean(np.abs(run.u_v) > lim))
    elif sc.effect == "backlash":
        out["width_counts"] = pl.transmission.gap_rad / step
    elif sc.effect == "compliance":
        twist = run.motor_true_rad - run.load_true_rad
        out["twist_rms_counts"] = float(np.std(twist) / step)
    if torque is not None:
        out.update(
            effect_torque_nm=torque,
            over_disturbance=torque / sc.disturbance_nm,
            over_count_torque=torque / sc.count_torque_nm(),
        )
    return out


def truth_of(sc: Scenario, run: Run) -> dict[str, object]:
    wb = sc.plant.workbench_truth()
    wb["delay.seconds"] = sc.delay_s
    m = sc.plant.motor
    hidden = {k: wb[k] for k in EFFECT_PARAMS.get(sc.effect or "", ())}
    return {
        "name": sc.name,
        "seed": sc.seed,
        "effect": sc.effect,
        "hidden_params": hidden,
        "axis": sc.axis,
        "gain_nm_per_v": m.gain_nm_per_v,
        "conditions": {
            "rate_hz": sc.rate_hz,
            "duration_s": sc.duration_s,
            "controller": sc.controller,
            "program": sc.program,
            "friction_law": sc.plant.law,
            "encoder": asdict(sc.encoder),
            "latency_ticks": sc.latency_ticks,
            "dither_v": sc.dither_v,
            "u_max_v": sc.u_max_v,
            "bandwidth_rad_s": sc.bandwidth_rad_s,
            "transmission": sc.plant.transmission.kind,
            "electrical_tau_ms": 1e3 * m.electrical_time_constant_s,
            "electrical_tau_samples": m.electrical_time_constant_s * sc.rate_hz,
            "disturbance_corr_s": sc.disturbance_corr_s,
        },
        "size": size_of_effect(sc, run),
        "workbench_truth": wb,
        "plant": sc.plant.as_dict(),
        "run": {
            "theta_span_rad": float(np.ptp(run.theta_rad)),
            "u_rms_v": float(np.sqrt(np.mean(run.u_v**2))),
            "u_peak_v": float(np.max(np.abs(run.u_v))),
        },
    }


def generate(
    out_dir: Path, name: str, seed: int, effect: str | None, duration_s: float = 20.0
) -> dict[str, object]:
    """Write out_dir/NAME.csv and out_dir/NAME.truth.json; returns the truth."""
    sc, run = build(name, seed, effect, duration_s)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_csv(str(out_dir / f"{name}.csv"), run)
    truth = truth_of(sc, run)
    (out_dir / f"{name}.truth.json").write_text(json.dumps(truth, indent=1, default=_jsonable))
    return truth


def _jsonable(v: object) -> object:
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    raise TypeError(type(v).__name__)


__all__ = ["EFFECT_PARAMS", "build", "generate"]
