"""The tick loop: read the encoder, compute the command, log it, hold it (delayed, ZOH) to the next tick."""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tests.truthgen.controllers import N_CTRL_STATE, controller_step
from tests.truthgen.encoder import quantize
from tests.truthgen.plant import N_STATE, TH_M, advance_interval

FloatArray = NDArray[np.float64]


@njit(cache=True)
def run_loop(
    P: FloatArray,
    kind: int,
    C: FloatArray,
    sig: FloatArray,
    noise: FloatArray,
    dist: FloatArray,
    period: float,
    total_delay: float,
    q: float,
    enc_mode: int,
    hmax: float,
    x0: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Run ``n = sig.shape[1]`` ticks and return the log and the true angles.

    Parameters
    ----------
    P : ndarray
        Packed plant parameters (:mod:`tests.truthgen.plant`).
    kind, C : int, ndarray
        Controller kind and coefficients (:mod:`tests.truthgen.controllers`).
    sig : ndarray, shape (N_SIG, n)
        Per-tick reference, its rate, feed-forward, dither and open-loop program.
    noise : ndarray, shape (n,)
        Measurement noise added to the motor angle before quantization, rad.
    dist : ndarray, shape (n + 1,)
        Load disturbance torque at the ticks (linear in between), N·m.
    period : float
        Sample period, s.
    total_delay : float
        Time from a tick to the moment its command reaches the amplifier, s
        (``delay.seconds`` plus ``latency_samples·period``). Fractions of a period are exact.
    q : float
        Encoder count, rad (0: none).
    enc_mode : int
        ``ENC_ROUND`` or ``ENC_TRUNC``.
    hmax : float
        Largest integration sub-step, s.
    x0 : ndarray
        Initial state (copied).

    Returns
    -------
    u : ndarray
        Logged command at each tick, V (u_i is held from t_i + total_delay).
    theta : ndarray
        Logged encoder reading at each tick, rad.
    theta_motor : ndarray
        True motor-side angle at each tick, rad (no noise, no quantization).
    theta_load : ndarray
        True load-side angle at each tick, rad.
    """
    n = sig.shape[1]
    x = x0.copy()
    S = np.zeros(N_CTRL_STATE)
    u = np.zeros(n)
    th = np.zeros(n)
    thm = np.zeros(n)
    thl = np.zeros(n)
    m = int(math.floor(total_delay / period + 1e-9))
    split = total_delay - m * period
    if split < 1e-12 * period:
        split = 0.0
    for i in range(n):
        thm[i] = x[TH_M]
        thl[i] = x[2]
        y = quantize(x[TH_M] + noise[i], q, enc_mode)
        th[i] = y
        u[i] = controller_step(kind, C, S, i, y, sig)
        # Over [t_i, t_{i+1}) the amplifier sees u_{i-m-1} until t_i + split, then u_{i-m}.
        j = i - m
        u_late = u[j] if j >= 0 else 0.0
        u_early = u[j - 1] if j - 1 >= 0 else 0.0
        if i < n - 1:
            advance_interval(x, P, period, split, u_early, u_late, dist[i], dist[i + 1], hmax)
    return u, th, thm, thl


def new_state() -> FloatArray:
    """A state at rest at angle 0, stuck, direction +1, belt in contact (``N_STATE`` floats)."""
    x = np.zeros(N_STATE)
    x[5] = 1.0
    x[6] = 1.0
    x[7] = 1.0
    return x
