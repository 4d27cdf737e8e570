"""Gravity unbalance torque: torque·sin(θ + phase)."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """τ = T_g·sin(θ + φ) at the load (the seed's b2 term, zero on pan)."""
    th = np.asarray(theta, dtype=float)
    return params["gravity.torque"] * np.sin(th + params["gravity.phase"])


EFFECT = Effect(
    name="gravity",
    kind="torque",
    description="Unbalanced load: a torque that follows sin(θ + phase).",
    params=(
        Param("torque", "N·m", 0.0, 0.0, 1e6, "unbalance torque amplitude"),
        Param("phase", "rad", 0.0, -np.pi, np.pi, "angle offset of the unbalance"),
    ),
    signature="residual torque follows sin θ",
    torque_nm=torque_nm,
    look_alikes=("offset", "ripple"),
    experiment="slow constant-speed moves over the widest angle range: the holding torque follows sin θ",
)
