"""Experiments on the practice rig, run the way a person runs them on a mount: the engine's own
controllers follow a scripted target on a simulated rig that hides the practice effect, and the
engine records t, u, theta (``Engine.start_recording``). Only the target scripts live here:

- ``steps``: random levels across ±60 % of the travel, held 0.8–2 s;
- ``sine_sweep``: a chirp 0.2 → 3 Hz around the centre, amplitude falling with frequency;
- ``slow_ramps``: triangles between random points at 2–25 °/s (low speed, reversals);
- ``mixed``: the workbench's own closed-loop excitation (steps, ramps and a sweep, with dither
  and a disturbance torque) from ``tracker.workbench.experiments.experiments.generate_measurement``.
"""

from __future__ import annotations

import asyncio
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.errors import ConfigError

EXPERIMENTS = ("mixed", "steps", "sine_sweep", "slow_ramps")
DT_S = 1e-3
FloatArray = NDArray[np.float64]


def target_script(kind: str, duration_s: float, limit_rad: float, seed: int) -> FloatArray:
    """The target of the exercised axis at 1 kHz for ``kind``. Returns shape (n,), rad."""
    rng = np.random.default_rng(seed)
    n = int(round(duration_s / DT_S))
    t = np.arange(n) * DT_S
    reach = 0.6 * limit_rad
    out = np.zeros(n)
    if kind == "steps":
        k = int(0.5 / DT_S)  # start from rest at 0
        while k < n:
            hold = int(rng.uniform(0.8, 2.0) / DT_S)
            out[k : k + hold] = rng.uniform(-reach, reach)
            k += hold
    elif kind == "sine_sweep":
        f0, f1 = 0.2, 3.0
        phase = 2 * math.pi * (f0 * t + 0.5 * (f1 - f0) / duration_s * t**2)
        freq = f0 + (f1 - f0) * t / duration_s
        amp = np.minimum(0.5 * reach, math.radians(8.0) / freq)  # keep speed and torque sane
        out = amp * np.sin(phase)
    elif kind == "slow_ramps":
        pos, k = 0.0, int(0.5 / DT_S)
        while k < n:
            goal = float(rng.uniform(-reach, reach))
            speed = math.radians(float(rng.uniform(2.0, 25.0)))
            m = max(1, int(abs(goal - pos) / speed / DT_S))
            seg = pos + (goal - pos) * np.arange(1, m + 1) / m
            out[k : k + m] = seg[: max(0, n - k)]
            k += m
            pos = goal
            out[k : k + int(0.3 / DT_S)] = pos  # a short hold at each end: starts from rest
            k += int(0.3 / DT_S)
    else:
        raise ConfigError(f"unknown experiment {kind!r}; experiments: {', '.join(EXPERIMENTS)}")
    return out


async def _run_engine(engine: Any, duration_s: float) -> None:
    await engine.run(realtime=False, duration_s=duration_s)


def record_experiment(truth: Any, axis: str, kind: str, duration_s: float, seed: int) -> Any:
    """Record one experiment on a rig whose ``axis`` is the practice model ``truth``.

    Returns the workbench Measurement of that axis (t s, u V, theta rad).
    """
    if kind not in EXPERIMENTS:
        raise ConfigError(f"unknown experiment {kind!r}; experiments: {', '.join(EXPERIMENTS)}")
    if kind == "mixed":
        from tracker.workbench.experiments.experiments import generate_measurement

        return generate_measurement(truth, duration_s=duration_s, seed=seed)
    from tracker.control.limits import SoftLimits
    from tracker.drivers.sim import SimDriver, rig_models
    from tracker.engine import Engine
    from tracker.targets import FunctionTarget

    models = dict(rig_models())
    models[axis] = truth if truth.has("quantization") else truth.with_effect("quantization")
    engine = Engine(SimDriver.from_models(models))
    script = target_script(kind, duration_s, SoftLimits.for_axis(axis).upper_rad, seed)
    last = script.size - 1

    def target(t_s: float) -> tuple[float, float]:
        value = float(script[min(last, max(0, int(round(t_s / DT_S))))])
        return (value, 0.0) if axis == "pan" else (0.0, value)

    engine.set_target_source(FunctionTarget(target, name=f"experiment:{kind}"))
    engine.set_tracking(True)
    engine.start_recording()
    asyncio.run(_run_engine(engine, duration_s))
    meas = engine.stop_recording()[axis]
    return meas
