"""Base effect: Coulomb friction Fc·sign(ω), sticking at rest while |applied torque| ≤ Fc."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """τ = Fc·sign(ω) (seed eq. 3.2)."""
    return np.asarray(params["coulomb.torque"] * np.sign(np.asarray(omega, dtype=float)), dtype=float)


EFFECT = Effect(
    name="coulomb",
    kind="base",
    description="Coulomb friction of constant magnitude opposing motion; sticks at rest.",
    params=(Param("torque", "N·m", 0.052, 0.0, 1e6, "Coulomb friction torque (positive direction)"),),
    signature="a step in the error at every velocity reversal",
    experiment=(
        "friction-ID sweep down to slow constant speeds (tracker friction-id): "
        "the friction torque at zero speed is Fc"
    ),
    torque_nm=torque_nm,
)
