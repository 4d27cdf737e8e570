"""Direction-dependent viscous friction: a different slope when moving in the negative direction."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """Extra torque over the symmetric viscous term: (b⁻ − b)·ω for ω < 0."""
    w = np.asarray(omega, dtype=float)
    delta = params["viscous_asymmetry.negative"] - params["viscous.b"]
    return np.where(w < 0.0, delta * w, 0.0)


EFFECT = Effect(
    name="viscous_asymmetry",
    kind="torque",
    description="Viscous friction differs by direction; viscous.b is then the positive one.",
    params=(Param("negative", "N·m·s/rad", 8.5e-4, 0.0, 1e6, "viscous coefficient when moving negative"),),
    signature="residual torque grows with speed differently in each direction",
    torque_nm=torque_nm,
    look_alikes=("coulomb_asymmetry", "offset"),
    experiment="friction-ID sweep (tracker friction-id): compare the slopes of the two directions",
)
