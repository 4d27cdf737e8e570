"""The scripted pointing test of ``tracker simulate``: steps, slow ramps, a 1 Hz sine, and its scores.

Script for one axis (20 s, repeated to fill a longer run)::

    0–0.5 s hold 0 · 0.5 s step to 30° · 3 s step back to 0 · 5–9 s ramp to 20° at 5 °/s ·
    9–13 s ramp back · 13–14 s hold · 14–20 s sine of amplitude A at 1 Hz (pan 20°, tilt 10°)

Scores (on the *load* angle, where the camera points): 10–90 % rise time, overshoot and 2 %
settling time of the 30° step; peak |error| over the sine's last 5 cycles in % of A (the
issue's ``sine_1hz_peak_error_percent``; the first cycle is the start-up transient); peak ramp
error; and the command's total variation per second (smoothness).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

SCRIPT_S = 20.0
STEP_RAD = math.radians(30.0)
STEP_AT_S, STEP_BACK_S = 0.5, 3.0
RAMP_RATE_RAD_S = math.radians(5.0)
RAMP_START_S, RAMP_TURN_S, RAMP_END_S = 5.0, 9.0, 13.0
SINE_START_S, SINE_SCORE_S, SINE_FREQ_HZ = 14.0, 15.0, 1.0
SINE_AMPLITUDE_RAD = {"pan": math.radians(20.0), "tilt": math.radians(10.0)}


def script_targets(axis: str, duration_s: float = SCRIPT_S, dt_s: float = 1e-3) -> FloatArray:
    """Target per sample for ``duration_s`` (the 20 s script, repeated). Shape (n,)."""
    n = int(round(duration_s / dt_s))
    t = (np.arange(n) * dt_s) % SCRIPT_S
    amp = SINE_AMPLITUDE_RAD[axis]
    r = np.zeros(n)
    r[(t >= STEP_AT_S) & (t < STEP_BACK_S)] = STEP_RAD
    up = (t >= RAMP_START_S) & (t < RAMP_TURN_S)
    r[up] = RAMP_RATE_RAD_S * (t[up] - RAMP_START_S)
    down = (t >= RAMP_TURN_S) & (t < RAMP_END_S)
    r[down] = RAMP_RATE_RAD_S * (RAMP_END_S - t[down])
    sine = t >= SINE_START_S
    r[sine] = amp * np.sin(2.0 * math.pi * SINE_FREQ_HZ * (t[sine] - SINE_START_S))
    return r


@dataclass(frozen=True, slots=True)
class PointingScores:
    """Scores of one script pass (see the module docstring)."""

    rise_time_s: float
    overshoot_percent: float
    settling_time_s: float
    sine_1hz_peak_error_percent: float
    ramp_peak_error_deg: float
    command_variation_v_per_s: float

    def to_dict(self) -> dict[str, float]:
        """JSON-ready, rounded for reading."""
        return {k: round(v, 4) for k, v in asdict(self).items()}


def score_pass(
    axis: str, theta_rad: FloatArray, u_v: FloatArray, dt_s: float = 1e-3, offset_s: float = 0.0
) -> PointingScores:
    """Score the script pass that starts ``offset_s`` into the arrays (shape (n,))."""
    k0 = int(round(offset_s / dt_s))

    def window(a: float, b: float) -> slice:
        return slice(k0 + int(round(a / dt_s)), k0 + int(round(b / dt_s)))

    step = theta_rad[window(STEP_AT_S, STEP_BACK_S)]
    t = np.arange(step.size) * dt_s
    above10 = np.flatnonzero(step >= 0.1 * STEP_RAD)
    above90 = np.flatnonzero(step >= 0.9 * STEP_RAD)
    rise = (above90[0] - above10[0]) * dt_s if above10.size and above90.size else math.inf
    overshoot = max(0.0, float(step.max() - STEP_RAD)) / STEP_RAD * 100.0
    outside = np.flatnonzero(np.abs(step - STEP_RAD) > 0.02 * STEP_RAD)
    settling = float(t[outside[-1]] + dt_s) if outside.size else 0.0
    if outside.size and outside[-1] == step.size - 1:
        settling = math.inf
    targets = script_targets(axis, SCRIPT_S, dt_s)
    w = window(SINE_SCORE_S, SCRIPT_S)
    sl = slice(int(round(SINE_SCORE_S / dt_s)), int(round(SCRIPT_S / dt_s)))
    sine_err = float(np.max(np.abs(theta_rad[w] - targets[sl])))
    wr = window(RAMP_START_S + 0.5, RAMP_END_S)
    slr = slice(int(round((RAMP_START_S + 0.5) / dt_s)), int(round(RAMP_END_S / dt_s)))
    ramp_err = float(np.max(np.abs(theta_rad[wr] - targets[slr])))
    one = window(0.0, SCRIPT_S)
    variation = float(np.sum(np.abs(np.diff(u_v[one])))) / SCRIPT_S
    return PointingScores(
        rise_time_s=float(rise),
        overshoot_percent=overshoot,
        settling_time_s=settling,
        sine_1hz_peak_error_percent=sine_err / SINE_AMPLITUDE_RAD[axis] * 100.0,
        ramp_peak_error_deg=math.degrees(ramp_err),
        command_variation_v_per_s=variation,
    )
