"""Direction-dependent Coulomb friction: a different torque when moving in the negative direction."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """Extra torque over the symmetric Coulomb term: (Fc⁻ − Fc⁺)·sign(ω) for ω < 0."""
    w = np.asarray(omega, dtype=float)
    delta = params["coulomb_asymmetry.negative"] - params["coulomb.torque"]
    return np.where(w < 0.0, -delta, 0.0)


EFFECT = Effect(
    name="coulomb_asymmetry",
    kind="torque",
    description="Coulomb friction differs by direction; coulomb.torque is then the positive one.",
    params=(Param("negative", "N·m", 0.052, 0.0, 1e6, "Coulomb torque when moving negative"),),
    signature="residual torque has a different mean in each direction of motion",
    torque_nm=torque_nm,
    look_alikes=("offset",),
    experiment=(
        "friction-ID sweep (tracker friction-id): per-direction Coulomb intercepts; repeat it at "
        "another position to tell direction-dependent friction from a bias torque"
    ),
)
