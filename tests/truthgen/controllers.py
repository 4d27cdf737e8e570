"""Discrete-time controllers of the generator (PID, lead/lag, PD+feed-forward, open loop, replay)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tests.truthgen.presets import AMPLIFIER_LIMIT_V, GAIN_NM_PER_V, Preset

FloatArray = NDArray[np.float64]

# Controller kinds.
CTRL_OPEN_LOOP = 0
CTRL_PID = 1
CTRL_LEADLAG = 2
CTRL_PDFF = 3
CTRL_REPLAY = 4

# Rows of the per-tick signal matrix handed to the compiled loop.
SIG_REF, SIG_RDOT, SIG_FF, SIG_DITHER, SIG_OL_A, SIG_OL_C, SIG_OL_FLAG = 0, 1, 2, 3, 4, 5, 6
N_SIG = 7
N_CTRL_STATE = 8


@dataclass(slots=True)
class ControllerDesign:
    """A designed controller: its kind, packed coefficients, and a readable description.

    Attributes
    ----------
    kind : int
        One of the ``CTRL_*`` codes.
    coeffs : ndarray
        Packed coefficients read by :func:`controller_step`.
    describe : dict
        Human-readable parameters (gains in V/rad, V·s/rad, V/(rad·s); times in s).
    """

    kind: int
    coeffs: FloatArray
    describe: dict[str, float | str] = field(default_factory=dict)


def design_pid(p: Preset, wc: float, period: float, zeta: float = 0.8) -> ControllerDesign:
    """PID with a filtered derivative on the measurement, placed on the nominal ``K/(J s²)``.

    Parameters
    ----------
    p : Preset
        Nominal axis (the truth is unknown to the controller).
    wc : float
        Closed-loop natural frequency, rad/s (15–30).
    period : float
        Sample period, s.
    zeta : float
        Damping ratio of the PD part.
    """
    kp = p.inertia * wc**2 / GAIN_NM_PER_V
    kd = 2.0 * zeta * wc * p.inertia / GAIN_NM_PER_V
    ki = kp * wc / 8.0
    tau_d = max(1.0 / (8.0 * wc), 2.0 * period)
    c = np.array([kp, ki, kd, tau_d, period, AMPLIFIER_LIMIT_V])
    return ControllerDesign(CTRL_PID, c, {"type": "pid", "kp": kp, "ki": ki, "kd": kd, "tau_d": tau_d})


def _tustin_first_order(a: float, b: float, period: float) -> tuple[float, float, float]:
    """Tustin discretisation of ``(s + a)/(s + b)``: ``y_k = b0 x_k + b1 x_{k-1} - a1 y_{k-1}``."""
    w = 2.0 / period
    den = w + b
    return (w + a) / den, (a - w) / den, (b - w) / den


def design_leadlag(p: Preset, wc: float, period: float) -> ControllerDesign:
    """Lead ``(s+wc/3)/(s+3wc)`` times lag ``(s+wc/10)/(s+wc/100)``, gain for crossover ``wc``.

    The lead gives ~53° at ``wc`` on the nominal double integrator; the lag raises the
    low-frequency gain tenfold (smaller Coulomb dead band). Both sections are discretised with
    Tustin at the sample period.
    """
    zl, pl = wc / 3.0, 3.0 * wc
    zg, pg = wc / 10.0, wc / 100.0
    # |lead(j wc)| = 1/3; |lag(j wc)| ≈ 1; plant |K/(J wc²)|.
    lag_mag = math.hypot(wc, zg) / math.hypot(wc, pg)
    kc = p.inertia * wc**2 / GAIN_NM_PER_V * 3.0 / lag_mag
    g0, g1, g2 = _tustin_first_order(zg, pg, period)
    l0, l1, l2 = _tustin_first_order(zl, pl, period)
    c = np.array([kc, g0, g1, g2, l0, l1, l2, AMPLIFIER_LIMIT_V])
    return ControllerDesign(
        CTRL_LEADLAG,
        c,
        {"type": "leadlag", "kc": kc, "lead_zero": zl, "lead_pole": pl, "lag_zero": zg, "lag_pole": pg},
    )


def design_pdff(p: Preset, wc: float, period: float, zeta: float = 0.75) -> ControllerDesign:
    """PD on the error (filtered measured rate) plus feed-forward of the nominal J, b, Fc."""
    kp = p.inertia * wc**2 / GAIN_NM_PER_V
    kd = 2.0 * zeta * wc * p.inertia / GAIN_NM_PER_V
    tau_d = max(1.0 / (8.0 * wc), 2.0 * period)
    c = np.array([kp, kd, tau_d, period, AMPLIFIER_LIMIT_V])
    return ControllerDesign(CTRL_PDFF, c, {"type": "pdff", "kp": kp, "kd": kd, "tau_d": tau_d})


def design_open_loop(range_rad: float) -> ControllerDesign:
    """Open-loop program; ``range_rad`` is where the operator turns pulses/bias back (rad)."""
    return ControllerDesign(
        CTRL_OPEN_LOOP, np.array([range_rad]), {"type": "open_loop", "recentre_rad": range_rad}
    )


def design_replay() -> ControllerDesign:
    """Replays the command in the ``SIG_OL_A`` row as is (tests, convergence checks)."""
    return ControllerDesign(CTRL_REPLAY, np.zeros(1), {"type": "replay"})


@njit(cache=True)
def _clip(u: float, lim: float) -> float:
    if u > lim:
        return lim
    if u < -lim:
        return -lim
    return u


@njit(cache=True)
def controller_step(kind: int, C: FloatArray, S: FloatArray, i: int, y: float, sig: FloatArray) -> float:
    """The command (V) at tick ``i`` from the encoder reading ``y`` (rad); updates state ``S``."""
    if kind == CTRL_REPLAY:
        return float(sig[SIG_OL_A, i])
    if kind == CTRL_OPEN_LOOP:
        # S[0]: sign applied to the pulse/oscillation program, S[1]: sign of the bias.
        if i == 0:
            S[0] = 1.0
            S[1] = 1.0
        if sig[SIG_OL_FLAG, i] > 0.0:
            a = sig[SIG_OL_A, i]
            S[0] = 1.0
            if abs(y) > C[0] and a * y > 0.0:
                S[0] = -1.0
            mag = abs(S[1])
            sgn = 1.0 if S[1] > 0.0 else -1.0
            if abs(y) > 0.5 * C[0]:
                sgn = -1.0 if y > 0.0 else 1.0
            if abs(y) > C[0]:
                mag = min(1.5 * mag, 5.0)
            else:
                mag = max(1.0, mag / 1.2)
            S[1] = sgn * mag
        return _clip(S[0] * sig[SIG_OL_A, i] + S[1] * sig[SIG_OL_C, i], 10.0)
    e = sig[SIG_REF, i] - y
    if kind == CTRL_PID:
        kp, ki, kd, tau_d, T, lim = C[0], C[1], C[2], C[3], C[4], C[5]
        # S: [integral, filtered rate, previous y]
        if i == 0:
            S[2] = y
        rate = (y - S[2]) / T
        S[2] = y
        S[1] += T / (tau_d + T) * (rate - S[1])
        integ = S[0] + e * T
        u = kp * e + ki * integ - kd * S[1] + sig[SIG_DITHER, i]
        if abs(u) <= lim:
            S[0] = integ  # conditional integration (anti-windup)
        return _clip(u, lim)
    if kind == CTRL_LEADLAG:
        kc = C[0]
        # lag section: S[0]=x_prev, S[1]=y_prev; lead section: S[2]=x_prev, S[3]=y_prev
        if i == 0:
            S[0] = e
            S[1] = e * (C[1] + C[2]) / (1.0 + C[3])  # start at the section's DC steady state
            S[2] = S[1]
            S[3] = S[1] * (C[4] + C[5]) / (1.0 + C[6])
        v1 = C[1] * e + C[2] * S[0] - C[3] * S[1]
        S[0], S[1] = e, v1
        v2 = C[4] * v1 + C[5] * S[2] - C[6] * S[3]
        S[2], S[3] = v1, v2
        return _clip(kc * v2 + sig[SIG_DITHER, i], C[7])
    if kind == CTRL_PDFF:
        kp, kd, tau_d, T, lim = C[0], C[1], C[2], C[3], C[4]
        if i == 0:
            S[2] = y
        rate = (y - S[2]) / T
        S[2] = y
        S[1] += T / (tau_d + T) * (rate - S[1])
        u = kp * e + kd * (sig[SIG_RDOT, i] - S[1]) + sig[SIG_FF, i] + sig[SIG_DITHER, i]
        return _clip(u, lim)
    return 0.0
