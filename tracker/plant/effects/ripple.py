"""Position-periodic torque ripple (cogging, gear mesh): amplitude·sin(n·θ + phase)."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """τ = A·sin(n·θ + φ), n cycles per load revolution."""
    th = np.asarray(theta, dtype=float)
    n = params["ripple.cycles_per_rev"]
    return params["ripple.amplitude"] * np.sin(n * th + params["ripple.phase"])


EFFECT = Effect(
    name="ripple",
    kind="torque",
    description="Torque that repeats with position, n times per revolution (cogging, gears).",
    params=(
        Param("amplitude", "N·m", 0.0, 0.0, 1e6, "ripple torque amplitude"),
        Param("cycles_per_rev", "1/rev", 21.0, 1.0, 500.0, "periods per load revolution"),
        Param("phase", "rad", 0.0, -np.pi, np.pi, "phase of the ripple"),
    ),
    signature="residual is periodic in θ",
    torque_nm=torque_nm,
    look_alikes=("gravity",),
    experiment=(
        "a slow constant-speed move over a full revolution (or the widest range): torque ripple vs θ"
    ),
)
