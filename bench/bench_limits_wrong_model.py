"""Benchmark: does the soft-limit guard hold when the controller's model is wrong? (prints figures)

Each run takes the seed preset as the rig (plus encoder quantization, and with ``--hidden`` the
rigid property test's hidden effects) and gives the controller a *wrong* model: the preset with
inertia, Coulomb friction and viscous friction each scaled by a factor drawn log-uniformly in
[1/``--spread``, ``--spread``] (what a fit to the log of another axis gives; the engineer's
"lighter axis" is inertia < 1). The gains are either designed on that wrong model (what
``PUT /axes/{axis}/model`` does) or random (both structures, any sign, |gain| 1e-3…1e5, as the
property test); the targets are random (holds, jumps, 20 Hz sines, ±1e6, NaN), shaped or not,
from a random start at rest. It prints the worst load angle past the limit (negative: the
closest approach stayed that far inside), per axis and kind of model error.

With a version of the engine whose ``simulate_closed_loop`` takes ``envelope``, the guard gets
the rig's rated braking envelope (``BrakingEnvelope.for_axis``), as the engine does; without it
(before the fix) the guard used the controller's model.

Run: ``.venv/bin/python bench/bench_limits_wrong_model.py --runs 300``.
"""

from __future__ import annotations

import argparse
import inspect
import math
import time
from typing import Any

import numpy as np

from bench.bench_limits_belt import random_gains, random_hidden, random_targets
from tracker.control import closed_loop
from tracker.control.closed_loop import simulate_closed_loop
from tracker.control.design import design_controller
from tracker.control.limits import SoftLimits
from tracker.control.trajectory import DEFAULT_LIMITS
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel

DT = 1e-3
SCALED = ("inertia.J", "coulomb.torque", "viscous.b")
HAS_ENVELOPE = "envelope" in inspect.signature(closed_loop.simulate_closed_loop).parameters


def wrong_model(rng: np.random.Generator, axis: str, spread: float) -> tuple[AxisModel, dict[str, float]]:
    """The preset with each of SCALED multiplied by a factor in [1/spread, spread] (log-uniform)."""
    base = AxisModel.for_axis(axis)
    factors = {k: float(spread ** rng.uniform(-1.0, 1.0)) for k in SCALED}
    return base.with_params({k: base.params[k] * f for k, f in factors.items()}), factors


def one_run(seed: tuple[int, ...], axis: str, spread: float, designed: bool, hidden: bool) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    limits = SoftLimits.for_axis(axis)
    lim = limits.upper_rad
    model, factors = wrong_model(rng, axis, spread)
    extra = random_hidden(rng) if hidden else {}
    effects = sorted({"quantization", *(k.split(".")[0] for k in extra)})
    plant = AxisModel.for_axis(axis, effects, extra)
    if designed:
        try:
            gains = design_controller(model, axis=axis).gains
        except ConfigError:
            gains = random_gains(rng)
    else:
        gains = random_gains(rng)
    shaped = rng.random() < 0.5
    kwargs: dict[str, Any] = {}
    if HAS_ENVELOPE:
        from tracker.control.envelope import BrakingEnvelope

        kwargs["envelope"] = BrakingEnvelope.for_axis(axis)
    r = simulate_closed_loop(
        plant,
        model,
        gains,
        random_targets(rng, lim),
        DT,
        limits,
        DEFAULT_LIMITS[axis] if shaped else None,
        theta0_rad=float(rng.uniform(-lim + 0.02, lim - 0.02)),
        **kwargs,
    )
    past = math.degrees(float(np.max(np.abs(r.load_theta_rad))) - lim)
    return {"seed": seed, "axis": axis, "factors": factors, "hidden": extra, "gains": gains, "past_deg": past}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=100, help="runs per axis and gain kind")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--spread", type=float, default=5.0, help="model factors in [1/spread, spread]")
    ap.add_argument("--hidden", action="store_true", help="add the property test's hidden effects")
    args = ap.parse_args()
    t0 = time.perf_counter()
    print(
        f"guard envelope: {'rated (BrakingEnvelope.for_axis)' if HAS_ENVELOPE else 'the controller model'}; "
        f"model factors in [1/{args.spread:g}, {args.spread:g}]; hidden effects: {args.hidden}; "
        f"{args.runs} runs per row; load past the limit (deg; negative: closest approach inside)"
    )
    print(f"{'axis':5s} {'gains':9s} {'model J':8s} {'worst':>8s} {'p99':>8s} {'median':>8s} passed")
    worst: dict[str, Any] | None = None
    for axis in ("pan", "tilt"):
        for designed in (True, False):
            seeds = [(args.seed, int(axis == "tilt"), int(designed), i) for i in range(args.runs)]
            runs = [one_run(s, axis, args.spread, designed, args.hidden) for s in seeds]
            for label, lighter in (("lighter", True), ("heavier", False)):
                past = np.array([r["past_deg"] for r in runs if (r["factors"]["inertia.J"] < 1.0) == lighter])
                if past.size == 0:
                    continue
                print(
                    f"{axis:5s} {'designed' if designed else 'random':9s} {label:8s} {past.max():+8.3f} "
                    f"{np.percentile(past, 99):+8.3f} {np.median(past):+8.3f} "
                    f"{int(np.sum(past > 0))}/{past.size}"
                )
            for r in runs:
                if worst is None or r["past_deg"] > worst["past_deg"]:
                    worst = r
    assert worst is not None
    print(f"worst run: {worst}")
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
