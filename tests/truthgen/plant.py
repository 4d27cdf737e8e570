"""The truth plant: one axis (rigid or two-mass) integrated by RK4 with exact Karnopp stick events."""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tests.truthgen.friction import LAW_LUGRE, breakaway, kinetic_torque, lugre

FloatArray = NDArray[np.float64]

# Parameter vector layout (see PlantParams.pack).
K, JM, JL, BP, BN, FCP, FCN, FEX, VS, DELTA = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9
OFFSET, TG, GPH, ULIM, RA, RN, RPH, BW, CK, CC = 10, 11, 12, 13, 14, 15, 16, 17, 18, 19
S0, S1, TWO, LAW = 20, 21, 22, 23
N_PARAMS = 24

# State vector layout: angles/velocities in load coordinates (rad, rad/s), LuGre bristle z (rad),
# modes: motor side stuck (1/0), sliding direction (±1), belt contact region (-1, 0, +1).
TH_M, OM_M, TH_L, OM_L, Z, STUCK, DIR, REG = 0, 1, 2, 3, 4, 5, 6, 7
N_STATE = 8

_MAX_EVENTS = 64  # events (stick, break-away, reversal) handled inside one sub-step
_ROOT_ITERS = 60


@njit(cache=True)
def _sat(u: float, lim: float) -> float:
    if u > lim:
        return lim
    if u < -lim:
        return -lim
    return u


@njit(cache=True)
def region_of(dx: float, P: FloatArray) -> float:
    """Contact region of belt twist ``dx`` (rad): -1, 0 (inside the dead band) or +1.

    Without backlash the belt is always in contact (+1).
    """
    half = 0.5 * P[BW]
    if half <= 0.0 or dx >= half:
        return 1.0
    if dx <= -half:
        return -1.0
    return 0.0


@njit(cache=True)
def _coupling_in(dx: float, dv: float, P: FloatArray, region: float) -> float:
    half = 0.5 * P[BW]
    if region > 0.0:
        return float(P[CK] * (dx - half) + P[CC] * dv)
    if region < 0.0:
        return float(P[CK] * (dx + half) + P[CC] * dv)
    return 0.0


@njit(cache=True)
def coupling_torque(dx: float, dv: float, P: FloatArray) -> float:
    """Belt torque (N·m) motor→load for twist ``dx`` (rad) and twist rate ``dv`` (rad/s)."""
    return _coupling_in(dx, dv, P, region_of(dx, P))


@njit(cache=True)
def _drive(
    thm: float, omm: float, thl: float, oml: float, P: FloatArray, u: float, dist: float, region: float
) -> float:
    tq = P[K] * _sat(u, P[ULIM]) - P[OFFSET] - P[RA] * math.sin(P[RN] * thm + P[RPH])
    if P[TWO] > 0.0:
        tq -= _coupling_in(thm - thl, omm - oml, P, region)
    else:
        tq += dist - P[TG] * math.sin(thm + P[GPH])
    return float(tq)


@njit(cache=True)
def drive_torque(
    thm: float, omm: float, thl: float, oml: float, P: FloatArray, u: float, dist: float
) -> float:
    """All non-friction torque on the motor side (on the whole axis when rigid), N·m."""
    return _drive(thm, omm, thl, oml, P, u, dist, region_of(thm - thl, P))


@njit(cache=True)
def _deriv(
    thm: float,
    omm: float,
    thl: float,
    oml: float,
    z: float,
    P: FloatArray,
    u: float,
    dist: float,
    stuck: bool,
    s: float,
    region: float,
) -> tuple[float, float, float, float, float]:
    """Time derivatives with the sliding direction ``s`` and the contact ``region`` held."""
    tq = _drive(thm, omm, thl, oml, P, u, dist, region)
    dz = 0.0
    if stuck:
        dthm = 0.0
        domm = 0.0
    elif P[LAW] == LAW_LUGRE:
        f, dz = lugre(omm, z, P[S0], P[S1], P[BP], P[FCP], P[FEX], P[VS])
        dthm = omm
        domm = (tq - f) / P[JM]
    else:
        f = kinetic_torque(omm, s, P[FCP], P[FCN], P[BP], P[BN], P[FEX], P[VS], P[DELTA])
        dthm = omm
        domm = (tq - f) / P[JM]
    if P[TWO] > 0.0:
        tl = _coupling_in(thm - thl, omm - oml, P, region) - P[TG] * math.sin(thl + P[GPH]) + dist
        return dthm, domm, oml, tl / P[JL], dz
    return dthm, domm, dthm, domm, dz


@njit(cache=True)
def _rk4(
    x: FloatArray, P: FloatArray, h: float, u: float, d0: float, ds: float, stuck: bool, s: float
) -> tuple[float, float, float, float, float]:
    """One classical RK4 step of length ``h`` from ``x`` (disturbance ``d0 + ds·τ``); pure.

    The modes (stuck, sliding direction ``s``, contact region ``x[REG]``) are held over the
    step, so the right-hand side is smooth and the step is fourth-order accurate.
    """
    r = x[REG]
    a0, a1, a2, a3, a4 = x[TH_M], x[OM_M], x[TH_L], x[OM_L], x[Z]
    k1 = _deriv(a0, a1, a2, a3, a4, P, u, d0, stuck, s, r)
    hh = 0.5 * h
    dm = d0 + ds * hh
    k2 = _deriv(
        a0 + hh * k1[0],
        a1 + hh * k1[1],
        a2 + hh * k1[2],
        a3 + hh * k1[3],
        a4 + hh * k1[4],
        P,
        u,
        dm,
        stuck,
        s,
        r,
    )
    k3 = _deriv(
        a0 + hh * k2[0],
        a1 + hh * k2[1],
        a2 + hh * k2[2],
        a3 + hh * k2[3],
        a4 + hh * k2[4],
        P,
        u,
        dm,
        stuck,
        s,
        r,
    )
    k4 = _deriv(
        a0 + h * k3[0],
        a1 + h * k3[1],
        a2 + h * k3[2],
        a3 + h * k3[3],
        a4 + h * k3[4],
        P,
        u,
        d0 + ds * h,
        stuck,
        s,
        r,
    )
    w = h / 6.0
    return (
        a0 + w * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
        a1 + w * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        a2 + w * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
        a3 + w * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]),
        a4 + w * (k1[4] + 2.0 * k2[4] + 2.0 * k3[4] + k4[4]),
    )


@njit(cache=True)
def _store(x: FloatArray, y: tuple[float, float, float, float, float], P: FloatArray) -> None:
    x[TH_M], x[OM_M], x[TH_L], x[OM_L], x[Z] = y
    if P[TWO] == 0.0:
        x[TH_L] = x[TH_M]
        x[OM_L] = x[OM_M]


@njit(cache=True)
def _margin(tq: float, P: FloatArray) -> float:
    """|torque| minus the break-away in its direction, N·m (≤ 0: the axis holds)."""
    if tq >= 0.0:
        return tq - breakaway(1.0, P[FCP], P[FCN], P[FEX])
    return -tq - breakaway(-1.0, P[FCP], P[FCN], P[FEX])


@njit(cache=True)
def _contact_gap(dx: float, P: FloatArray, region: float) -> float:
    """Distance (rad) to leaving ``region``: > 0 inside it, ≤ 0 once left."""
    half = 0.5 * P[BW]
    if region > 0.0:
        return float(dx - half)
    if region < 0.0:
        return float(-dx - half)
    return float(half - abs(dx))


@njit(cache=True)
def _event_value(
    y: tuple[float, float, float, float, float], P: FloatArray, kind: int, s: float, region: float
) -> float:
    if kind == 0:
        return s * y[1]
    return _contact_gap(y[0] - y[2], P, region)


@njit(cache=True)
def _locate(
    x: FloatArray,
    P: FloatArray,
    rem: float,
    u: float,
    d0: float,
    ds: float,
    stuck: bool,
    s: float,
    kind: int,
    lo: float,
    glo: float,
    ghi: float,
) -> float:
    """Fraction of ``rem`` at which event ``kind`` (0: velocity zero, 1: contact change) occurs.

    Illinois root finding of the event function along the RK4 flow from ``x``, bracketed by
    ``g(lo) = glo > 0`` and ``g(1) = ghi <= 0``; returns the upper end of the final bracket
    (the event has happened there).
    """
    hi = 1.0
    side = 0
    for _k in range(_ROOT_ITERS):
        a = (lo * ghi - hi * glo) / (ghi - glo)
        if not (lo < a < hi):
            a = 0.5 * (lo + hi)
        ga = _event_value(_rk4(x, P, a * rem, u, d0, ds, stuck, s), P, kind, s, x[REG])
        if ga > 0.0:
            lo, glo = a, ga
            if side == -1:
                ghi *= 0.5
            side = -1
        else:
            hi, ghi = a, ga
            if side == 1:
                glo *= 0.5
            side = 1
        if ga <= 0.0 and ga > -1e-15:
            break
        if hi - lo < 1e-13:
            break
    return hi


@njit(cache=True)
def _enter_region(x: FloatArray, P: FloatArray) -> None:
    """After a contact event: the belt leaves the dead band (to ±1) or leaves contact (to 0)."""
    if x[REG] == 0.0:
        x[REG] = 1.0 if x[TH_M] - x[TH_L] > 0.0 else -1.0
    else:
        x[REG] = 0.0


@njit(cache=True)
def substep(x: FloatArray, P: FloatArray, h: float, u: float, d0: float, ds: float) -> None:
    """Advance state ``x`` in place by ``h`` seconds at constant applied command ``u`` (V).

    The disturbance on the load is ``d0 + ds·τ`` (N·m) over the step. Every RK4 step holds the
    modes (stuck or sliding direction, belt contact region), so the integrated right-hand side is
    smooth; mode changes inside the step are events located on the RK4 flow (Illinois):

    * a sliding motor side whose velocity reaches zero stops there and is tested for sticking
      (|drive torque| ≤ break-away in its direction, Karnopp) or reverses;
    * a stuck motor side holds exactly until the drive torque exceeds the break-away (the
      crossing instant is interpolated in the step);
    * with backlash, the belt entering or leaving contact (twist crossing ±width/2).

    LuGre has no events (its bristle state is integrated with the rest).
    """
    if P[LAW] == LAW_LUGRE:
        _store(x, _rk4(x, P, h, u, d0, ds, False, 1.0), P)
        return
    two = P[TWO] > 0.0
    backlash = two and P[BW] > 0.0
    rem = h
    tau = 0.0  # time since the start of the sub-step
    for _ in range(_MAX_EVENTS):
        if rem <= 1e-16 * h:
            return
        dnow = d0 + ds * tau
        reg = x[REG]
        if x[STUCK] > 0.0:
            t0 = _drive(x[TH_M], 0.0, x[TH_L], x[OM_L], P, u, dnow, reg)
            m0 = _margin(t0, P)
            if m0 > 0.0:
                x[STUCK] = 0.0
                x[DIR] = 1.0 if t0 > 0.0 else -1.0
                continue
            frac = 1.0
            if two:
                y = _rk4(x, P, rem, u, dnow, ds, True, 1.0)
                if backlash:
                    g1 = _contact_gap(y[0] - y[2], P, reg)
                    if g1 <= 0.0:
                        g0 = _contact_gap(x[TH_M] - x[TH_L], P, reg)
                        frac = _locate(x, P, rem, u, dnow, ds, True, 1.0, 1, 0.0, g0, g1)
                        y = _rk4(x, P, frac * rem, u, dnow, ds, True, 1.0)
            else:
                y = (x[TH_M], 0.0, x[TH_M], 0.0, x[Z])
            t1 = _drive(y[0], 0.0, y[2], y[3], P, u, dnow + ds * frac * rem, reg)
            m1 = _margin(t1, P)
            if m1 > 0.0:  # breaks away inside [0, frac]
                hs = frac * rem * m0 / (m0 - m1)
                if two and hs > 0.0:
                    _store(x, _rk4(x, P, hs, u, dnow, ds, True, 1.0), P)
                x[OM_M] = 0.0
                if not two:
                    x[OM_L] = 0.0
                tau += hs
                rem -= hs
                x[STUCK] = 0.0
                x[DIR] = 1.0 if t1 > 0.0 else -1.0
                continue
            _store(x, y, P)
            x[OM_M] = 0.0
            if not two:
                x[OM_L] = 0.0
            hs = frac * rem
            tau += hs
            rem -= hs
            if frac < 1.0:
                _enter_region(x, P)
            continue
        s = x[DIR]
        y = _rk4(x, P, rem, u, dnow, ds, False, s)
        vel_event = s * y[1] <= 0.0
        con_event = backlash and _contact_gap(y[0] - y[2], P, reg) <= 0.0
        if not vel_event and not con_event:
            _store(x, y, P)
            return
        fv = 2.0
        if vel_event:
            g0 = s * x[OM_M]
            lo = 0.0
            if g0 <= 0.0:  # starting from rest: find a point where it is under way
                a = 0.5
                for _k in range(40):
                    ya = _rk4(x, P, a * rem, u, dnow, ds, False, s)
                    if s * ya[1] > 0.0:
                        lo = a
                        g0 = s * ya[1]
                        break
                    a *= 0.5
            if g0 > 0.0:
                fv = _locate(x, P, rem, u, dnow, ds, False, s, 0, lo, g0, s * y[1])
            else:
                fv = 0.0  # cannot get under way: stop now
        fc = 2.0
        if con_event:
            g0 = _contact_gap(x[TH_M] - x[TH_L], P, reg)
            fc = _locate(x, P, rem, u, dnow, ds, False, s, 1, 0.0, g0, _contact_gap(y[0] - y[2], P, reg))
        if fc < fv:  # the belt's contact changes first
            hs = fc * rem
            _store(x, _rk4(x, P, hs, u, dnow, ds, False, s), P)
            tau += hs
            rem -= hs
            _enter_region(x, P)
            continue
        hs = fv * rem
        if hs > 0.0:
            _store(x, _rk4(x, P, hs, u, dnow, ds, False, s), P)
        x[OM_M] = 0.0
        if not two:
            x[OM_L] = 0.0
        tau += hs
        rem -= hs
        tq = _drive(x[TH_M], 0.0, x[TH_L], x[OM_L], P, u, d0 + ds * tau, x[REG])
        if _margin(tq, P) <= 0.0:
            x[STUCK] = 1.0
        else:
            x[DIR] = 1.0 if tq > 0.0 else -1.0
    if rem > 1e-16 * h:  # event storm (should not happen): finish the step in the current modes
        _store(x, _rk4(x, P, rem, u, d0 + ds * tau, ds, x[STUCK] > 0.0, x[DIR]), P)


@njit(cache=True)
def advance_interval(
    x: FloatArray,
    P: FloatArray,
    period: float,
    split: float,
    u_early: float,
    u_late: float,
    d0: float,
    d1: float,
    hmax: float,
) -> None:
    """Advance ``x`` over one sample period with the command switching inside it.

    Parameters
    ----------
    x : ndarray
        State (modified in place).
    P : ndarray
        Packed parameters.
    period : float
        Sample period, s.
    split : float
        Time after the tick at which the applied command switches from ``u_early`` to
        ``u_late``, s (0: ``u_late`` over the whole period). Sub-steps are aligned on it.
    u_early, u_late : float
        Applied commands before/after ``split``, V.
    d0, d1 : float
        Load disturbance at the start and end of the period (linear in between), N·m.
    hmax : float
        Largest sub-step, s.
    """
    ds = (d1 - d0) / period
    if split > 0.0:
        n1 = int(math.ceil(split / hmax - 1e-9))
        h1 = split / n1
        for k in range(n1):
            substep(x, P, h1, u_early, d0 + ds * k * h1, ds)
    rest = period - split
    n2 = int(math.ceil(rest / hmax - 1e-9))
    h2 = rest / n2
    for k in range(n2):
        substep(x, P, h2, u_late, d0 + ds * (split + k * h2), ds)
