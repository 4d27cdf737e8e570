"""The camera model's angle along a log: exact piecewise integration of a speed-commanded axis.

Command j (signed speed v_j, rad/s) acts from t_j + latency until the next one acts. The drive's
speed follows it at most ``accel`` rad/s² (infinite: at once); the drive angle integrates the
speed; the measured angle follows the drive through a dead band of ``width`` (it stays put
until the drive has crossed the play). Between events the speed is a ramp then a constant, so
every piece is integrated exactly (a ramp that crosses zero is split there, where the drive
reverses), and the result is exact for any latency and any row spacing — no time step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.workbench.camera.log import CameraLog
from tracker.workbench.camera.model import CameraModel

FloatArray = NDArray[np.float64]


@njit(cache=True)
def _piece(
    m: float, v: float, load: float, h: float, target: float, accel: float, half: float
) -> tuple[float, float, float]:
    """Advance (drive angle, speed, measured angle) by ``h`` toward ``target`` (one piece)."""
    if h <= 0.0:
        return m, v, load
    if not math.isfinite(accel):
        m += target * h
        v = target
    else:
        dv = target - v
        t_ramp = abs(dv) / accel
        a = accel if dv > 0 else -accel
        if t_ramp > h:
            t_ramp = h
        # the drive reverses inside the ramp: clamp the load at the turning point first
        if v != 0.0 and (a > 0) != (v > 0):
            t_zero = abs(v) / accel
            if t_zero < t_ramp:
                m += v * t_zero + 0.5 * a * t_zero * t_zero
                load = min(max(load, m - half), m + half)
                v = 0.0
                h -= t_zero
                t_ramp -= t_zero
        m += v * t_ramp + 0.5 * a * t_ramp * t_ramp
        v += a * t_ramp
        if h > t_ramp:
            v = target if t_ramp > 0.0 or dv == 0.0 else v
            m += v * (h - t_ramp)
    return m, v, min(max(load, m - half), m + half)


@njit(cache=True)
def _run(t_s: FloatArray, speeds: FloatArray, latency_s: float, accel: float, width: float) -> FloatArray:
    n = t_s.size
    out = np.zeros(n)
    half = 0.5 * width
    m = 0.0
    v = 0.0
    load = 0.0
    target = 0.0
    now = t_s[0]
    i = 1
    j = 0
    while i < n:
        t_out = t_s[i]
        t_sw = t_s[j] + latency_s if j < n else math.inf
        if t_sw <= t_out:
            m, v, load = _piece(m, v, load, t_sw - now, target, accel, half)
            now = t_sw
            target = speeds[j]
            j += 1
        else:
            m, v, load = _piece(m, v, load, t_out - now, target, accel, half)
            now = t_out
            out[i] = load
            i += 1
    return out


def simulate_angles(
    t_s: FloatArray,
    speeds_rad_s: FloatArray,
    *,
    latency_s: float = 0.0,
    accel_rad_s2: float = math.inf,
    backlash_rad: float = 0.0,
) -> FloatArray:
    """The measured angle at each row time, relative to the first (rad, shape (n,)).

    ``speeds_rad_s[j]`` is the signed speed commanded at ``t_s[j]`` (see the module docstring)."""
    return _run(
        np.ascontiguousarray(t_s, dtype=np.float64),
        np.ascontiguousarray(speeds_rad_s, dtype=np.float64),
        float(latency_s),
        float(accel_rad_s2),
        float(backlash_rad),
    )


def model_angles(log: CameraLog, model: CameraModel) -> FloatArray:
    """The model's angle along ``log`` relative to its first row (rad, shape (n,))."""
    return simulate_angles(
        log.t_s,
        model.speeds_rad_s(log.step),
        latency_s=model.effective_latency_s,
        accel_rad_s2=model.effective_accel_rad_s2,
        backlash_rad=model.effective_backlash_rad,
    )
