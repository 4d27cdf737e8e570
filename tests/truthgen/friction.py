"""Friction laws of the truth plant: kinetic Coulomb/viscous/Stribeck, break-away, and LuGre."""

from __future__ import annotations

import math

from numba import njit

#: Law codes understood by the integrator.
LAW_KINETIC = 0  # Karnopp stick + Coulomb/viscous (+ Stribeck excess): karnopp, stribeck
LAW_LUGRE = 1  # LuGre bristle model with pre-sliding (rigid axis only)


@njit(cache=True)
def kinetic_torque(
    omega: float,
    s: float,
    fc_pos: float,
    fc_neg: float,
    b_pos: float,
    b_neg: float,
    f_excess: float,
    vs: float,
    delta: float,
) -> float:
    """Friction torque (N·m, opposing motion) of a sliding axis moving in direction ``s``.

    Parameters
    ----------
    omega : float
        Velocity, rad/s (has the sign of ``s`` while sliding).
    s : float
        Direction of sliding, +1 or -1. Held fixed over an integration step so the law is smooth
        in ``omega`` within the step; a zero crossing is located by the integrator.
    fc_pos, fc_neg : float
        Coulomb torque moving positive / negative, N·m.
    b_pos, b_neg : float
        Viscous coefficient moving positive / negative, N·m·s/rad.
    f_excess : float
        Stribeck excess ``Fs - Fc`` at zero speed, N·m (0: no Stribeck term).
    vs : float
        Stribeck velocity, rad/s.
    delta : float
        Stribeck exponent (1 or 2).

    Returns
    -------
    float
        ``s·(Fc_s + (Fs−Fc)·exp(−(|ω|/vs)^δ)) + b_s·ω``, N·m.
    """
    if s > 0.0:
        fc = fc_pos
        b = b_pos
    else:
        fc = fc_neg
        b = b_neg
    mag = fc
    if f_excess > 0.0:
        a = s * omega / vs
        if delta == 2.0:
            mag += f_excess * math.exp(-a * a)
        elif delta == 1.0:
            mag += f_excess * math.exp(-a)
        else:
            mag += f_excess * math.exp(-(abs(a) ** delta))
    return s * mag + b * omega


@njit(cache=True)
def breakaway(s: float, fc_pos: float, fc_neg: float, f_excess: float) -> float:
    """Break-away torque (N·m, positive) of an axis at rest pushed in direction ``s``."""
    if s > 0.0:
        return fc_pos + f_excess
    return fc_neg + f_excess


@njit(cache=True)
def lugre(
    omega: float,
    z: float,
    sigma0: float,
    sigma1: float,
    b: float,
    fc: float,
    f_excess: float,
    vs: float,
) -> tuple[float, float]:
    """LuGre friction torque and bristle rate.

    Parameters
    ----------
    omega : float
        Velocity, rad/s.
    z : float
        Mean bristle deflection, rad.
    sigma0 : float
        Bristle stiffness, N·m/rad.
    sigma1 : float
        Bristle damping, N·m·s/rad.
    b : float
        Viscous coefficient (σ2), N·m·s/rad.
    fc : float
        Coulomb torque, N·m.
    f_excess : float
        Stribeck excess ``Fs - Fc``, N·m (0 for the clean cases: steady state is Coulomb+viscous).
    vs : float
        Stribeck velocity, rad/s.

    Returns
    -------
    tuple of float
        Friction torque (N·m) and dz/dt (rad/s). In steady sliding the torque is
        ``g(ω)·sign(ω) + b·ω`` with ``g(ω) = Fc + (Fs−Fc)·exp(−(ω/vs)²)``.
    """
    g = fc
    if f_excess > 0.0:
        a = omega / vs
        g += f_excess * math.exp(-a * a)
    dz = omega - sigma0 * abs(omega) * z / g
    return sigma0 * z + sigma1 * dz + b * omega, dz
