"""A constant bias torque (cable drag, unbalance on a linear axis, amplifier offset)."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """τ = offset, resisting: J θ'' = K u − ... − offset (the EMPS reference model's sign)."""
    return np.full_like(np.asarray(omega, dtype=float), params["offset.torque"])


EFFECT = Effect(
    name="offset",
    kind="torque",
    description="Constant bias torque, the same whatever the position or velocity.",
    params=(Param("torque", "N·m", 0.0, -1e6, 1e6, "constant resisting torque"),),
    signature="residual torque has a constant non-zero mean",
    torque_nm=torque_nm,
    look_alikes=("coulomb_asymmetry", "gravity"),
    experiment=(
        "repeat the friction-ID sweep (tracker friction-id) at a different position or with the "
        "load rebalanced: a bias torque (cable, unbalance) changes with them, friction does not"
    ),
)
