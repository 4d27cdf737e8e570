"""The velocity observer: a Luenberger observer of angle, velocity and lumped disturbance torque.

Model (seed eq. 3.2 with the Coulomb term lumped into an unknown torque d)::

    J ω' = K u − b ω + d,   θ' = ω,   d' = 0

discretised with the simulator's semi-implicit Euler at Ts. Only the encoder angle is
measured; the observer runs in *current* form (the sample's measurement corrects the estimate
before the command is computed), so its velocity is smooth through encoder quantization,
unlike the seed's differentiated encoder (seed ch. 4: "friction cancellation ... made the
response very jerky"). The disturbance state absorbs friction and unmodelled torques, so the
velocity estimate has no steady bias.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control
import numpy as np
from numpy.typing import NDArray

from tracker.errors import ConfigError
from tracker.plant.model import AxisModel

FloatArray = NDArray[np.float64]
N_OBS = 3  # [θ, ω, d]
# Pole spread of the three observer poles, as multiples of the bandwidth.
POLE_SPREAD = (1.0, 1.25, 1.5)


@dataclass(frozen=True, slots=True)
class ObserverMatrices:
    """Discrete observer x⁻ₖ₊₁ = A x̂ₖ + B uₖ, x̂ₖ = x⁻ₖ + L (yₖ − C x⁻ₖ); shapes (3,3), (3,), (3,)."""

    a: FloatArray
    b: FloatArray
    c: FloatArray
    l: FloatArray  # noqa: E741 - the textbook name of the observer gain


def plant_matrices(model: AxisModel, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """Semi-implicit Euler model of [θ, ω, d] driven by u (V). Returns A (3,3) and B (3,)."""
    j = model.params["inertia.J"]
    b = model.params["viscous.b"]
    k = model.gain_nm_per_v
    decay = 1.0 - dt_s * b / j
    a = np.array(
        [
            [1.0, dt_s * decay, dt_s * dt_s / j],
            [0.0, decay, dt_s / j],
            [0.0, 0.0, 1.0],
        ]
    )
    bu = np.array([dt_s * dt_s * k / j, dt_s * k / j, 0.0])
    return a, bu


def design_observer(model: AxisModel, bandwidth_hz: float, dt_s: float) -> ObserverMatrices:
    """Place the observer's error poles at exp(−POLE_SPREAD·2π·bandwidth·Ts) (Ackermann)."""
    if not (math.isfinite(bandwidth_hz) and 0.0 < bandwidth_hz < 0.25 / dt_s):
        raise ConfigError(
            f"observer bandwidth {bandwidth_hz!r} Hz must be positive and below {0.25 / dt_s:g} Hz"
        )
    a, bu = plant_matrices(model, dt_s)
    c = np.array([1.0, 0.0, 0.0])
    w = 2.0 * math.pi * bandwidth_hz
    poles = [math.exp(-s * w * dt_s) for s in POLE_SPREAD]
    # Current-form error dynamics are (A − A L C): place A L = L', the predictor gain.
    l_pred = np.asarray(control.acker(a.T, c.reshape(-1, 1), poles)).reshape(-1)
    l_cur = np.linalg.solve(a, l_pred)
    return ObserverMatrices(a, bu, c, l_cur)
