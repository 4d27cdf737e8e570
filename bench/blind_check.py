"""Blind check of the workbench through its command-line contract, on data it has never seen.

Generates closed-loop measurements on the twin with a controller and excitation of its own (a
PID with a filtered derivative, different from the workbench's experiment generator), hides one
effect (or none, or two) at random physical parameters, writes CSV logs, then runs
``tracker model diagnose --json`` and ``tracker model fit --json`` as an outside tool would and
scores the verdicts and the recovered parameters.

    .venv/bin/python bench/blind_check.py [--seeds 2] [--effects gravity,delay] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

from tracker.plant.model import AxisModel
from tracker.plant.simulate import advance, encoder_rad, pack_params
from tracker.workbench.measurements.data import Measurement, write_log

DT_S = 1e-3


def random_hidden(effect: str, rng: np.random.Generator, base: AxisModel) -> dict[str, float]:
    """Physically plausible parameters for a hidden effect on the pan axis."""
    fc, b = base.params["coulomb.torque"], base.params["viscous.b"]
    u = rng.uniform
    table: dict[str, dict[str, float]] = {
        "coulomb_asymmetry": {
            "coulomb_asymmetry.negative": fc * float(rng.choice([u(0.45, 0.7), u(1.4, 1.9)]))
        },
        "viscous_asymmetry": {"viscous_asymmetry.negative": b * u(1.6, 2.6)},
        "offset": {"offset.torque": float(rng.choice([-1, 1])) * u(0.012, 0.03)},
        "stiction": {"stiction.static_torque": fc * u(1.5, 2.2), "stiction.velocity": u(0.02, 0.08)},
        "gravity": {"gravity.torque": u(0.03, 0.08), "gravity.phase": u(-math.pi, math.pi)},
        "delay": {"delay.seconds": u(0.006, 0.025)},
        "saturation": {"saturation.limit": u(2.0, 4.0)},
        "ripple": {
            "ripple.amplitude": u(0.006, 0.015),
            "ripple.cycles_per_rev": float(rng.integers(8, 40)),
            "ripple.phase": u(-math.pi, math.pi),
        },
        "backlash": {"backlash.width": u(0.006, 0.03)},
        "compliance": {"compliance.frequency": u(8.0, 25.0), "compliance.damping": u(0.04, 0.2)},
    }
    return table[effect]


def excitation(n: int, rng: np.random.Generator) -> np.ndarray:
    """Targets (rad): steps, a slow triangle, and a chirp, shuffled in order per seed."""
    t = np.arange(n) * DT_S
    third = n // 3
    steps = np.repeat(rng.uniform(-0.7, 0.7, size=10), int(math.ceil(third / 10)))[:third]
    tri_t = t[:third]
    tri = 0.6 * (2 * np.abs(((tri_t / 8.0) % 1.0) - 0.5) * 2 - 1)
    ch_t = t[: n - 2 * third]
    f = 0.1 + (2.5 - 0.1) * ch_t / max(ch_t[-1], 1e-9)
    chirp = 0.25 * np.sin(2 * np.pi * np.cumsum(f) * DT_S)
    parts = [steps, tri, chirp]
    order = rng.permutation(3)
    return np.concatenate([parts[i] for i in order])


@njit(cache=True)
def _closed_loop(P, target, dither, dist, kp, kd, ki, tau_d):  # pragma: no cover - compiled
    n = target.shape[0]
    u = np.zeros(n)
    theta = np.empty(n)
    x = np.zeros(4)
    integ = 0.0
    d_filt = 0.0
    prev = 0.0
    a = DT_S / (tau_d + DT_S)
    for k in range(n):
        y = encoder_rad(x, P)
        theta[k] = y
        e = target[k] - y
        d_raw = (y - prev) / DT_S if k > 0 else 0.0
        prev = y
        d_filt += a * (d_raw - d_filt)
        integ += e * DT_S
        v = kp * e - kd * d_filt + ki * integ + dither[k]
        if v > 10.0:
            v = 10.0
            integ -= e * DT_S
        elif v < -10.0:
            v = -10.0
            integ -= e * DT_S
        u[k] = v
        advance(x, P, u, k, DT_S, dist[k])
    return u, theta


def generate(true_model: AxisModel, seed: int, duration_s: float = 30.0) -> Measurement:
    rng = np.random.default_rng(seed)
    n = int(duration_s / DT_S)
    P = pack_params(true_model, DT_S, quantize=True)
    target = excitation(n, rng)
    dither = 0.15 * rng.standard_normal(n)
    # Disturbance torque: zero-mean noise band-limited to ~2 Hz, 1 mN·m RMS (2 % of Coulomb), so
    # that no hidden bias or position-dependent torque sneaks in through it.
    from scipy.signal import butter, sosfiltfilt

    dist = sosfiltfilt(butter(2, 2.0, fs=1.0 / DT_S, output="sos"), rng.standard_normal(n))
    dist = 1e-3 * (dist - dist.mean()) / dist.std()
    u, theta = _closed_loop(P, target, dither, dist, 30.0, 1.2, 20.0, 0.004)
    return Measurement(np.arange(n) * DT_S, u, theta, f"blind-{seed}")


def run_cli(args: list[str]) -> dict:
    out = subprocess.run([sys.executable, "-m", "tracker", *args, "--json"], capture_output=True, text=True)
    if out.returncode != 0:
        return {"error": (out.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(out.stdout)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--effects", default="")
    ap.add_argument("--pairs", action="store_true", help="also hide pairs of effects")
    ap.add_argument("--keep", default="")
    a = ap.parse_args()
    base = AxisModel.for_axis("pan", ["quantization"])
    effects = [e for e in a.effects.split(",") if e] or [
        "coulomb_asymmetry",
        "viscous_asymmetry",
        "offset",
        "stiction",
        "gravity",
        "delay",
        "saturation",
        "ripple",
        "backlash",
        "compliance",
    ]
    cases: list[tuple[str, ...]] = [()] + [(e,) for e in effects]
    if a.pairs:
        cases += [("gravity", "delay"), ("offset", "ripple"), ("stiction", "backlash")]
    folder = Path(a.keep or tempfile.mkdtemp(prefix="blind-"))
    folder.mkdir(parents=True, exist_ok=True)
    print(
        f"{'hidden':32s} {'seed':>4s} {'verdict':20s} {'ok':3s} {'fit% before':>11s} {'after':>7s} "
        f"{'diag s':>6s}  param errors"
    )
    correct = total = 0
    for case in cases:
        for seed in range(a.seeds):
            rng = np.random.default_rng(1000 + seed + 97 * len(case) + sum(map(ord, "".join(case))))
            truth: dict[str, float] = {}
            for e in case:
                truth.update(random_hidden(e, rng, base))
            true_model = AxisModel.for_axis("pan", ["quantization", *case], truth)
            meas = generate(true_model, int(rng.integers(1 << 30)))
            path = folder / f"{'+'.join(case) or 'clean'}-{seed}.csv"
            write_log(path, meas)
            t0 = time.perf_counter()
            d = run_cli(["model", "diagnose", str(path), "--axis", "pan"])
            dt = time.perf_counter() - t0
            verdict = d.get("verdict", d.get("error"))
            ok = (
                (verdict is None)
                if not case
                else (verdict in case or ("coulomb_asymmetry" in case and verdict == "offset"))
            )
            correct += ok
            total += 1
            errs = ""
            after = float("nan")
            if case and verdict in case:
                f = run_cli(["model", "fit", str(path), "--axis", "pan", "--effects", verdict])
                after = f.get("fit_percent", float("nan"))
                parts = []
                for k, v in truth.items():
                    if k.startswith(verdict + ".") and k in f.get("params", {}) and not k.endswith("phase"):
                        parts.append(f"{k.split('.')[1]} {100 * (f['params'][k] - v) / v:+.0f}%")
                errs = ", ".join(parts)
            print(
                f"{'+'.join(case) or 'clean':32s} {seed:4d} {str(verdict):20s} {'yes' if ok else 'NO':3s} "
                f"{d.get('fit_percent', float('nan')):11.2f} {after:7.2f} {dt:6.1f}  {errs}",
                flush=True,
            )
    print(f"\nverdicts right: {correct}/{total}  (logs in {folder})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
