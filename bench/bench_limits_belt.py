"""Benchmark: how far past its soft limit can a belt-driven axis go? (random search, prints figures)

Each run draws a belt (compliance 5–50 Hz, damping 0.02–0.5, optional backlash ≤ 0.23°),
random gains of both structures (|gain| 1e-3…1e5, either sign), random targets (holds, jumps,
20 Hz sines, ±1e6, NaN), a random start at rest (inside the belt guard's lines when the model
knows the belt, inside the rigid guard's line otherwise), and hidden motor-side effects within
the guard's assumptions (offset, Coulomb asymmetry, stiction, delay ≤ 3 ms, amplifier clip
≥ 7 V, ripple; gravity on the load side). The design model is either the seed's rigid model
(the guard does not know of the belt: ``--model rigid``, with ``--site-margin-hz F
[--site-damping Z]`` for the site margin of an unknown belt at least F Hz stiff and damped Z)
or the seed's model plus the true belt (``--model belt``: a fitted compliance). It prints the
worst overshoot past the limit of the load (the camera) and of the encoder (the motor), per
axis and belt band, and the worst run's recipe.

Run: ``.venv/bin/python bench/bench_limits_belt.py --runs 200 --model belt``, or for an unknown
belt ``... --model rigid --site-margin-hz 30 --damping 0.1-0.5 --bands 30-60,60-300 --runs 1000``.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

import numpy as np

from tracker.control.closed_loop import simulate_closed_loop
from tracker.control.gains import ControllerGains, LeadGains, ObserverPdGains
from tracker.control.limits import (
    GUARD_MARGIN_RAD,
    UNKNOWN_BELT_MIN_DAMPING,
    SoftLimits,
    belt_guard_lines,
    unknown_belt_margin_rad,
)
from tracker.control.trajectory import DEFAULT_LIMITS
from tracker.plant.model import AxisModel

DT = 1e-3
N = 3000


def _signed(rng: np.random.Generator) -> float:
    mag = 10.0 ** rng.uniform(-3.0, 5.0)
    return float(mag if rng.random() < 0.75 else -mag)


def random_gains(rng: np.random.Generator) -> ControllerGains:
    """Gains of either structure, any sign, |gain| from 1e-3 to 1e5 (as the property test)."""
    if rng.random() < 0.25:
        return LeadGains(_signed(rng), float(rng.uniform(-1.5, 1.5)), float(rng.uniform(-1.2, 1.2)))
    return ObserverPdGains(
        kp_v_per_rad=_signed(rng),
        kd_v_s_per_rad=_signed(rng),
        ki_v_per_rad_s=0.0 if rng.random() < 0.3 else _signed(rng),
        observer_bandwidth_hz=float(rng.uniform(0.2, 240.0)),
        feedforward=float(rng.uniform(-5.0, 5.0)),
        friction_comp=float(rng.uniform(-5.0, 5.0)),
        friction_band_rad_s=float(10.0 ** rng.uniform(-4.0, 0.0)),
        integral_limit_v=float(rng.uniform(0.0, 100.0)),
        disturbance_comp=float(rng.uniform(-2.0, 2.0)),
        friction_adapt_per_s=float(rng.uniform(0.0, 1000.0)),
    )


def random_targets(rng: np.random.Generator, limit_rad: float) -> np.ndarray:
    """Holds, jumps and fast sines over 3 s, often far past the limits. Shape (N,)."""
    out = np.empty(N)
    k = 0
    while k < N:
        length = min(int(rng.integers(50, 1500)), N - k)
        kind = rng.choice(["hold", "sine", "huge"])
        t = np.arange(length) * DT
        if kind == "hold":
            out[k : k + length] = rng.uniform(-3 * limit_rad, 3 * limit_rad)
        elif kind == "sine":
            out[k : k + length] = rng.uniform(0, 3 * limit_rad) * np.sin(
                2 * math.pi * rng.uniform(0.1, 20) * t
            )
        else:
            out[k : k + length] = rng.choice([1e6, -1e6, np.nan, np.inf])
        k += length
    return out


def random_hidden(rng: np.random.Generator, gravity_nm: float = 0.12) -> dict[str, float]:
    """Hidden effects within the guard's assumptions (limits.py), up to four of them; hidden
    gravity (on the load side) up to ``gravity_nm``."""
    draws = {
        "gravity": lambda: {
            "gravity.torque": rng.uniform(0, gravity_nm),
            "gravity.phase": rng.uniform(-3.1, 3.1),
        },
        "offset": lambda: {"offset.torque": rng.uniform(-0.06, 0.06)},
        "coulomb_asymmetry": lambda: {"coulomb_asymmetry.negative": rng.uniform(0.02, 0.1)},
        "stiction": lambda: {"stiction.static_torque": rng.uniform(0.06, 0.12)},
        "delay": lambda: {"delay.seconds": rng.uniform(0.0, 0.003)},
        "saturation": lambda: {"saturation.limit": rng.uniform(7.0, 10.0)},
        "ripple": lambda: {"ripple.amplitude": rng.uniform(0.0, 0.03)},
        "backlash": lambda: {"backlash.width": rng.uniform(0.0, 0.004)},
    }
    names = rng.choice(sorted(draws), size=int(rng.integers(0, 5)), replace=False)
    out: dict[str, float] = {}
    for n in names:
        out.update({k: float(v) for k, v in draws[str(n)]().items()})
    return out


@dataclass(frozen=True, slots=True)
class Run:
    seed: tuple[int, ...]
    axis: str
    freq_hz: float
    damping: float
    hidden: dict[str, float]
    gains: ControllerGains
    load_past_deg: float
    encoder_past_deg: float


def one_run(
    seed: tuple[int, ...],
    axis: str,
    known: bool,
    band: tuple[float, float],
    gravity_nm: float = 0.12,
    freq_error: float = 0.0,
    site_margin_hz: float | None = None,
    damping: tuple[float, float] = (0.02, 0.5),
    damping_error: float = 1.0,
    site_damping: float = UNKNOWN_BELT_MIN_DAMPING,
) -> Run:
    rng = np.random.default_rng(seed)
    limits = SoftLimits.for_axis(axis)
    if site_margin_hz is not None:  # the site knows only that its belt is at least this stiff
        margin = unknown_belt_margin_rad(AxisModel.for_axis(axis), site_margin_hz, site_damping)
        limits = SoftLimits.for_axis(axis, GUARD_MARGIN_RAD + margin)
    lim = limits.upper_rad
    freq = float(rng.uniform(*band))
    zeta = float(10.0 ** rng.uniform(math.log10(damping[0]), math.log10(damping[1])))
    belt = {"compliance.frequency": freq, "compliance.damping": zeta}
    hidden = random_hidden(rng, gravity_nm)
    effects = sorted({"quantization", "compliance", *(k.split(".")[0] for k in hidden)})
    plant = AxisModel.for_axis(axis, effects, {**belt, **hidden})
    # The guard's model: the belt as fitted, its frequency off by up to ±freq_error (relative).
    fitted = {
        "compliance.frequency": freq * (1.0 + freq_error * rng.uniform(-1.0, 1.0)),
        "compliance.damping": zeta * damping_error ** rng.uniform(-1.0, 1.0),
    }
    design = AxisModel.for_axis(axis, ["compliance"], fitted) if known else AxisModel.for_axis(axis)
    gains = random_gains(rng)
    shaped = rng.random() < 0.5
    # The axis starts at rest inside the guard's lines (both guards' assumption): the belt
    # guard's lines when the model knows the belt, the limits less the guard margin otherwise.
    line = lim - limits.guard_margin_rad
    start_lo, start_hi = belt_guard_lines(design, limits) if known else (-line, line)
    r = simulate_closed_loop(
        plant,
        design,
        gains,
        random_targets(rng, lim),
        DT,
        limits,
        DEFAULT_LIMITS[axis] if shaped else None,
        theta0_rad=float(rng.uniform(start_lo + 0.02, start_hi - 0.02)),
    )
    load = float(np.max(np.abs(r.load_theta_rad))) - lim
    enc = float(np.max(np.abs(r.theta_rad))) - lim
    return Run(seed, axis, freq, zeta, hidden, gains, math.degrees(load), math.degrees(enc))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=60, help="runs per axis and belt band")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--gravity", type=float, default=0.12, help="hidden load-side gravity bound (N·m)")
    ap.add_argument("--freq-error", type=float, default=0.0, help="fitted belt frequency error (relative)")
    ap.add_argument(
        "--site-margin-hz",
        type=float,
        default=None,
        help="guard margin for an unknown belt at least this stiff (unknown_belt_margin_rad)",
    )
    ap.add_argument(
        "--site-damping",
        type=float,
        default=UNKNOWN_BELT_MIN_DAMPING,
        help="the damping ratio the site margin assumes the unknown belt has at least",
    )
    ap.add_argument(
        "--damping-error", type=float, default=1.0, help="fitted damping off by up to this factor"
    )
    ap.add_argument("--damping", default="0.02-0.5", help="belt damping ratio range, log-uniform")
    ap.add_argument("--bands", default="5-10,10-20,20-50", help="belt bands in Hz, e.g. 20-50,50-100")
    ap.add_argument("--model", choices=("rigid", "belt"), default="belt", help="what the guard's model knows")
    args = ap.parse_args()
    t0 = time.perf_counter()
    bands = [(float(b.split("-")[0]), float(b.split("-")[1])) for b in args.bands.split(",")]
    damping = (float(args.damping.split("-")[0]), float(args.damping.split("-")[1]))
    if args.site_margin_hz is not None:
        hz, zeta = args.site_margin_hz, args.site_damping
        pan, tilt = (
            math.degrees(unknown_belt_margin_rad(AxisModel.for_axis(a), hz, zeta)) for a in ("pan", "tilt")
        )
        print(
            f"site guard margin for a belt of at least {hz:g} Hz, damping ≥ {zeta:g}: pan {pan:.2f}°, "
            f"tilt {tilt:.2f}° (plus {math.degrees(GUARD_MARGIN_RAD):g}°)"
        )
    print(
        f"design model: {args.model} (belt frequency error ≤ ±{100 * args.freq_error:g} %); hidden gravity "
        f"≤ {args.gravity:g} N·m; {args.runs} runs per axis "
        "and band; overshoot past the limit (deg; negative: the closest approach stayed that far inside)"
    )
    print(f"{'axis':5s} {'belt band':>11s} {'load worst':>11s} {'load p99':>9s} {'enc worst':>10s} passed")
    worst_all: Run | None = None
    for axis in ("pan", "tilt"):
        for band in bands:
            runs = [
                one_run(
                    (args.seed, int(axis == "tilt"), int(band[0]), i),
                    axis,
                    args.model == "belt",
                    band,
                    args.gravity,
                    args.freq_error,
                    args.site_margin_hz,
                    damping,
                    args.damping_error,
                    args.site_damping,
                )
                for i in range(args.runs)
            ]
            load = np.array([r.load_past_deg for r in runs])
            enc = np.array([r.encoder_past_deg for r in runs])
            print(
                f"{axis:5s} {band[0]:4.0f}-{band[1]:3.0f} Hz {load.max():11.3f} "
                f"{np.percentile(load, 99):9.3f} {enc.max():10.3f} "
                f"{int(np.sum(load > 0)):4d}/{len(runs)}"
            )
            w = max(runs, key=lambda r: r.load_past_deg)
            if worst_all is None or w.load_past_deg > worst_all.load_past_deg:
                worst_all = w
    assert worst_all is not None
    print(
        f"worst (seed {worst_all.seed}): {worst_all.axis} {worst_all.freq_hz:.1f} Hz "
        f"ζ={worst_all.damping:.3f} load "
        f"{worst_all.load_past_deg:.2f}° past, hidden {worst_all.hidden}, gains {worst_all.gains}"
    )
    print(f"wall {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
