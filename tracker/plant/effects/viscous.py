"""Base effect: viscous friction b·ω."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """τ = b·ω (seed eq. 3.2)."""
    return params["viscous.b"] * np.asarray(omega, dtype=float)


EFFECT = Effect(
    name="viscous",
    kind="base",
    description="Viscous friction proportional to velocity.",
    params=(Param("b", "N·m·s/rad", 8.5e-4, 0.0, 1e6, "viscous friction coefficient"),),
    signature="errors grow with speed",
    experiment=(
        "friction-ID sweep at several constant speeds (tracker friction-id): "
        "the friction torque's slope over speed is b"
    ),
    torque_nm=torque_nm,
)
