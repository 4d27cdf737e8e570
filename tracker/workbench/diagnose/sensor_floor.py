"""The sensor's share of the residual torque: what the encoder alone leaves in inverse dynamics.

The screening regresses ``K·u`` on ``J·α + b·ω + Fc·sign ω + …`` with α and ω differentiated from
the encoder's angle. A count's step and the reading's white noise, differentiated twice, put a
torque of their own into the residual that no effect can explain: on a coarse encoder it is most
of what a model with the right effects leaves (1000 counts per revolution at 1 kHz: the ripple
a second round should find explained 7 % of the residual torque, and cut the k-step error by
14 % at t = 10). A share of the residual torque is then a share of mostly sensor.

:func:`sensor_torque_sse` reads the sensor through the log's own trajectory: the smoothed angle
is read again through the encoder step and white noise found in the log (random phase of the
count grid, fresh noise), passed through the same filter and derivatives, and the torque the
regression's J, b and Fc make of the difference is summed over the samples the regressions use.
It is the expected sum of squares of the sensor's part of the residual (the disturbance is left
out, so it is a lower bound of what a right model leaves).

On a coarse encoder the regression's inertia is itself the sensor's doing: α differentiated
twice from the counts carries noise of the size of its signal, and least squares on a noisy
column shrinks its coefficient (errors in variables: Ĵ = J·σ²_α / (σ²_α + σ²_n)). What that
regression leaves is then not Ĵ²·σ²_n but J·Ĵ·σ²_n: the sensor's torque at Ĵ plus the inertial
torque (J − Ĵ)·α the shrunken column no longer carries, and neither is a function of θ or of the
direction of motion. Given the inertia the k-step simulation judges by (``inertia_sim``, which
never differentiates the encoder), the α term is weighted by √(J·Ĵ) instead of Ĵ (9191 held-out
coulomb_asymmetry-007, 500 counts per revolution at 250 Hz: Ĵ = 0.00041 against J = 0.0030; the
floor 11 % of the residual at Ĵ, 78 % at √(J·Ĵ)).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tracker.workbench.compare.floor import SensorNoise
from tracker.workbench.measurements.idim import Regression, Signals

FloatArray = NDArray[np.float64]
SENSOR_REPLICAS = 3  # readings drawn; their mean sum of squares is the estimate
SENSOR_SEED = 20260  # fixed: the same log gives the same floor


def _states(sig: Signals, theta_rad: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    th = sig.lowpass(theta_rad)
    om = np.gradient(th, sig.dt_s)
    al = np.gradient(om, sig.dt_s)
    return om, al, sig.lowpass(np.sign(om))


def sensor_torque_sse(sig: Signals, reg: Regression, inertia_sim: float | None = None) -> float:
    """Expected sum of squares (N·m)² of the sensor's torque at the used samples (see module doc).

    ``reg`` supplies J (``Jm``, plus ``Jl`` when there is a load column), b and Fc. ``inertia_sim``
    (kg·m²), when larger than the regression's J, is the inertia the simulation judges by: the α
    term is then weighted by their geometric mean (errors in variables, see module doc). Returns
    0 when the log shows neither a count step nor white noise.
    """
    noise = SensorNoise.from_log(sig.theta_raw_rad)
    q, white = noise.encoder_step_rad, noise.white_noise_rad
    if q <= 0.0 and white <= 0.0:
        return 0.0
    c = dict(zip(reg.names, reg.coef, strict=True))
    j = c.get("Jm", 0.0) + c.get("Jl", 0.0)
    if inertia_sim is not None and inertia_sim > j > 0.0:
        j = math.sqrt(j * inertia_sim)
    b, fc = c.get("b", 0.0), c.get("Fc", 0.0)
    smooth = sig.theta_rad
    om0, al0, s0 = _states(sig, smooth)
    rng = np.random.default_rng(SENSOR_SEED)
    total = 0.0
    for _ in range(SENSOR_REPLICAS):
        th = smooth + white * rng.standard_normal(smooth.size) if white > 0 else smooth.copy()
        if q > 0:
            th = q * np.round(th / q + rng.uniform())
        om, al, s = _states(sig, th)
        d = (j * (al - al0) + b * (om - om0) + fc * (s - s0))[sig.use]
        total += float(d @ d)
    return total / SENSOR_REPLICAS


__all__ = ["sensor_torque_sse"]
