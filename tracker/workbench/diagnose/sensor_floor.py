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
"""

from __future__ import annotations

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


def sensor_torque_sse(sig: Signals, reg: Regression) -> float:
    """Expected sum of squares (N·m)² of the sensor's torque at the used samples (see module doc).

    ``reg`` supplies J (``Jm``, plus ``Jl`` when there is a load column), b and Fc. Returns 0 when
    the log shows neither a count step nor white noise.
    """
    noise = SensorNoise.from_log(sig.theta_raw_rad)
    q, white = noise.encoder_step_rad, noise.white_noise_rad
    if q <= 0.0 and white <= 0.0:
        return 0.0
    c = dict(zip(reg.names, reg.coef, strict=True))
    j = c.get("Jm", 0.0) + c.get("Jl", 0.0)
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
