"""Closed-loop identification runs on the twin: a PD loop following steps, ramps and a sweep.

This is how the workbench makes synthetic measurements with known parameters (tests,
benchmarks, the console's "record a test run" on the simulated rig). The loop is the kind a
real mount runs: PD on the encoder angle with a filtered finite-difference velocity, command
clipped at ±10 V, dither on the command, a slowly varying disturbance torque on the load and
encoder quantization (when the model has ``quantization``, or ``quantize_step_rad`` is given).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.plant.model import AxisModel
from tracker.plant.simulate import I_Q, advance, encoder_rad, initial_state, pack_params
from tracker.units import AMPLIFIER_LIMIT_V
from tracker.workbench.measurements.data import Measurement

FloatArray = NDArray[np.float64]


def reference_rad(
    duration_s: float, dt_s: float, amplitude_rad: float, rng: np.random.Generator
) -> FloatArray:
    """Steps, slow ramps and a 0.2–4 Hz sine sweep, each a third of the run. Shape (n,)."""
    n = int(round(duration_s / dt_s))
    t = np.arange(n, dtype=np.float64) * dt_s
    ref = np.zeros(n)
    third = n // 3
    # Steps: random levels held 0.6–1.5 s.
    k = 0
    while k < third:
        hold = int(rng.uniform(0.6, 1.5) / dt_s)
        ref[k : min(k + hold, third)] = rng.uniform(-amplitude_rad, amplitude_rad)
        k += hold
    # Ramps: triangle waves at random slow speeds between the step part's end and ± amplitude.
    k = third
    pos = ref[third - 1]
    while k < 2 * third:
        target = rng.uniform(-amplitude_rad, amplitude_rad)
        speed = rng.uniform(0.03, 0.6) * amplitude_rad
        m = max(1, int(abs(target - pos) / speed / dt_s))
        m = min(m, 2 * third - k)
        ref[k : k + m] = np.linspace(pos, target, m, endpoint=False)
        pos = ref[k + m - 1]
        k += m
    # Sine sweep around the last ramp position, ramping in to avoid a jump.
    ts = t[2 * third :] - t[2 * third]
    span = max(ts[-1], dt_s)
    f0, f1 = 0.2, 4.0
    phase = 2.0 * math.pi * (f0 * ts + 0.5 * (f1 - f0) * ts**2 / span)
    amp = 0.5 * amplitude_rad * np.minimum(1.0, ts / 0.5) * (1.0 - 0.6 * ts / span)
    ref[2 * third :] = pos * (1.0 - np.minimum(1.0, ts / 1.0)) + amp * np.sin(phase)
    return ref


@njit(cache=True)
def _closed_loop(
    P: FloatArray,
    ref: FloatArray,
    dither: FloatArray,
    dist: FloatArray,
    dt: float,
    kp: float,
    kd: float,
    vel_tau: float,
    x0: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    n = ref.shape[0]
    u = np.zeros(n)
    y = np.zeros(n)
    x = x0.copy()
    prev = encoder_rad(x, P)
    vel = 0.0
    a = dt / (vel_tau + dt)
    for k in range(n):
        meas = encoder_rad(x, P)
        y[k] = meas
        vel += a * ((meas - prev) / dt - vel)
        prev = meas
        v = kp * (ref[k] - meas) - kd * vel + dither[k]
        if v > 10.0:
            v = 10.0
        elif v < -10.0:
            v = -10.0
        u[k] = v
        advance(x, P, u, k, dt, dist[k])
    return u, y


def closed_loop_log(
    model: AxisModel,
    duration_s: float = 30.0,
    dt_s: float = 1e-3,
    seed: int = 0,
    amplitude_rad: float = 0.6,
    bandwidth_hz: float = 4.0,
    dither_v: float = 0.05,
    disturbance_nm: float = 0.0,
    quantize_step_rad: float | None = None,
) -> Measurement:
    """Record a closed-loop run of ``model`` on the simulator (the encoder angle as ``theta``).

    Parameters
    ----------
    model : the "true" plant.
    duration_s, dt_s : length and sample time of the log.
    seed : random seed of the reference, dither and disturbance.
    amplitude_rad : reach of the reference around 0.
    bandwidth_hz : PD loop natural frequency (gains from the linearised plant K/J).
    dither_v : standard deviation of white dither added to the command, V.
    disturbance_nm : standard deviation of a slowly varying (≈1 Hz) load torque, N·m.
    quantize_step_rad : encoder count; None uses the model's ``quantization`` effect if any.

    Returns
    -------
    Measurement with ``u`` the clipped command actually sent (V).
    """
    rng = np.random.default_rng(seed)
    n = int(round(duration_s / dt_s))
    ref = reference_rad(duration_s, dt_s, amplitude_rad, rng)
    P = pack_params(model, dt_s, quantize=True)
    if quantize_step_rad is not None:
        P[I_Q] = quantize_step_rad
    plant_gain = model.gain_nm_per_v / model.params["inertia.J"]
    w = 2.0 * math.pi * bandwidth_hz
    kp = w * w / plant_gain
    kd = 2.0 * 0.7 * w / plant_gain
    dither = rng.normal(0.0, dither_v, n)
    if disturbance_nm > 0.0:
        raw = rng.normal(0.0, 1.0, n)
        alpha = dt_s / (0.16 + dt_s)
        dist = np.empty(n)
        acc = 0.0
        for k in range(n):
            acc += alpha * (raw[k] - acc)
            dist[k] = acc
        dist *= disturbance_nm / max(float(np.std(dist)), 1e-12)
    else:
        dist = np.zeros(n)
    u, y = _closed_loop(P, ref, dither, dist, dt_s, kp, kd, 0.004, initial_state(float(ref[0])))
    assert np.all(np.abs(u) <= AMPLIFIER_LIMIT_V)
    t = np.arange(n, dtype=np.float64) * dt_s
    return Measurement(t, u, y, f"twin:{','.join(model.effects) or 'base'}:seed{seed}")


__all__ = ["closed_loop_log", "reference_rad"]
