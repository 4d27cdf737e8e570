"""The fast fixed-step simulator of one axis with any set of effects (the digital twin's core).

Equation of motion (seed eq. 3.2 plus the catalogue), in load coordinates::

    J θ'' = K·sat(u(t − d)) − b(ω)·ω − F(ω)·sign(ω) − offset − ripple(θ) − gravity(θ) + τ_dist

with Karnopp stick at rest (the axis holds while |applied torque| ≤ break-away torque) and a
Stribeck term when ``stiction`` is on. With ``backlash`` or ``compliance`` the inertia splits
into a motor side (friction, offset, ripple, the encoder) and a load side (gravity, external
disturbance) joined by a belt spring with a dead band.

Integration is leapfrog (staggered semi-implicit Euler) with sub-steps sized to the belt
resonance: angles live at the sample instants and velocities half a sub-step earlier, so the
velocity kick over [t − h/2, t + h/2] takes the command averaged over that interval. With the
command zero-order-held per sample this is exact for the rigid axis between friction events,
whatever the sample rate: the twin answers a command at the same instant a continuous-time
axis would (a plain semi-implicit Euler step answers half a sample early, which a fit of real
data reads as a half-sample delay). The delay is applied the same way, exactly, by averaging
the delayed held command, so results vary smoothly with ``delay.seconds``.

Effects that are not built in (generic effects, :mod:`tracker.plant.effects`) are torques of
the angle alone, τ(θ). Compiled code cannot call their Python functions, so :func:`pack_params`
tabulates their sum on a fine grid of θ and appends the table to the packed vector; the motor
side takes the linearly interpolated torque (beyond the table's ends, the end value).

Everything hot is compiled with numba: the closed-loop simulator in ``tracker.control`` calls
:func:`advance` and :func:`encoder_rad` directly from its own compiled loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.errors import ConfigError, DataError
from tracker.plant.effects import CATALOGUE, is_generic
from tracker.plant.effects.quantization import SEED_ENCODER_STEP_RAD
from tracker.plant.effects.saturation import clip_level_v, drive_rail_v
from tracker.plant.model import AxisModel
from tracker.units import AMPLIFIER_LIMIT_V

FloatArray = NDArray[np.float64]

# Packed parameter vector layout (see pack_params). Literal indices keep numba's cache honest.
I_K, I_JM, I_JL, I_BP, I_BN, I_FCP, I_FCN, I_FS, I_VS = 0, 1, 2, 3, 4, 5, 6, 7, 8
I_OFFSET, I_GT, I_GPH, I_DELAY, I_ULIM, I_RA, I_RN, I_RPH = 9, 10, 11, 12, 13, 14, 15, 16
I_BW, I_CK, I_CC, I_Q, I_TWO, I_STIC, I_NSUB = 17, 18, 19, 20, 21, 22, 23
# The generic torque table: first angle (rad), step (rad), length; its values follow N_PACKED.
I_TAB0, I_TABH, I_TABN = 24, 25, 26
N_PACKED = 27

# The table spans the data's angles plus this margin each side, at this step (16384 points over
# ±2π: linear interpolation errs by (n·step)²/8 of a torque with n cycles per revolution, 4e-6
# at n = 7); a longer span gets more points, up to TABLE_MAX_POINTS.
TABLE_MARGIN_RAD = 2.0 * math.pi
TABLE_STEP_RAD = 4.0 * math.pi / 16383
TABLE_MAX_POINTS = 1 << 18

# Backlash without a compliance effect still needs a contact: a stiff, well-damped belt.
CONTACT_FREQUENCY_HZ = 150.0
CONTACT_DAMPING = 0.5
# Sub-step so that ω_res·h stays below this (explicit coupling stays accurate and stable).
MAX_OMEGA_H = 0.3

# State vector: [θ_motor, ω_motor, θ_load, ω_load] (rad, rad/s).
STATE_SIZE = 4


def generic_torque_table(
    model: AxisModel, range_rad: tuple[float, float] = (0.0, 0.0)
) -> tuple[float, float, FloatArray]:
    """The summed torque (N·m, resisting) of ``model``'s generic effects at rest on a grid of θ.

    The grid covers ``range_rad`` (the angles the run is expected to visit) plus
    :data:`TABLE_MARGIN_RAD` each side. Returns (first angle, step, values of shape (m,)); m = 0
    when the model has no generic effect.
    """
    names = [e for e in model.effects if is_generic(e)]
    if not names:
        return 0.0, 1.0, np.zeros(0)
    lo, hi = min(range_rad) - TABLE_MARGIN_RAD, max(range_rad) + TABLE_MARGIN_RAD
    n = int(min(TABLE_MAX_POINTS, max(2, math.ceil((hi - lo) / TABLE_STEP_RAD) + 1)))
    theta = np.linspace(lo, hi, n)
    rest = np.zeros_like(theta)
    total = np.zeros_like(theta)
    for name in names:
        tau = np.asarray(CATALOGUE[name].torque_nm(model.params, theta, rest), dtype=float)
        if tau.shape != theta.shape or not np.all(np.isfinite(tau)):
            bad = theta[~np.isfinite(tau)] if tau.shape == theta.shape else theta[:0]
            where = f" at θ = {bad[0]:.4g} rad" if bad.size else f" (shape {tau.shape})"
            raise ConfigError(f"the torque of effect {name!r} is not a finite array over θ{where}")
        total += tau
    return float(lo), float(theta[1] - theta[0]), total


def pack_params(
    model: AxisModel,
    dt_s: float,
    quantize: bool = True,
    range_rad: tuple[float, float] = (0.0, 0.0),
    rail_v: float = AMPLIFIER_LIMIT_V,
) -> FloatArray:
    """Pack ``model`` into the simulator's parameter vector for sample time ``dt_s``.

    Disabled effects get neutral values (no offset, symmetric friction, the drive's rail, ...),
    so the compiled code needs no branches per effect. The command is clipped at ``rail_v`` (the
    drive's rail, V: the rig's amplifier by default; a log's own,
    :func:`~tracker.plant.effects.saturation.drive_rail_v`, in the workbench) or lower at a
    saturation's limit. Generic effects become a torque table over ``range_rad`` ± 2π (see
    :func:`generic_torque_table`). Returns shape (N_PACKED + m,), m the table's length (0
    without generic effects).
    """
    p = model.params
    P = np.zeros(N_PACKED)
    j = p["inertia.J"]
    two_mass = model.has("backlash") or model.has("compliance")
    frac = p["inertia.motor_fraction"] if two_mass else 1.0
    P[I_K] = model.gain_nm_per_v
    P[I_JM] = j * frac
    P[I_JL] = j * (1.0 - frac)
    P[I_BP] = p["viscous.b"]
    P[I_BN] = p.get("viscous_asymmetry.negative", p["viscous.b"])
    P[I_FCP] = p["coulomb.torque"]
    P[I_FCN] = p.get("coulomb_asymmetry.negative", p["coulomb.torque"])
    P[I_STIC] = 1.0 if model.has("stiction") else 0.0
    P[I_FS] = p.get("stiction.static_torque", 0.0)
    P[I_VS] = p.get("stiction.velocity", 1.0)
    P[I_OFFSET] = p.get("offset.torque", 0.0)
    P[I_GT] = p.get("gravity.torque", 0.0)
    P[I_GPH] = p.get("gravity.phase", 0.0)
    P[I_DELAY] = p.get("delay.seconds", 0.0)
    P[I_ULIM] = clip_level_v(p, rail_v)
    P[I_RA] = p.get("ripple.amplitude", 0.0)
    P[I_RN] = p.get("ripple.cycles_per_rev", 1.0)
    P[I_RPH] = p.get("ripple.phase", 0.0)
    P[I_BW] = p.get("backlash.width", 0.0)
    P[I_Q] = p.get("quantization.step", 0.0) if (quantize and model.has("quantization")) else 0.0
    n_sub = 1
    if two_mass:
        f_hz = p.get("compliance.frequency", CONTACT_FREQUENCY_HZ)
        zeta = p.get("compliance.damping", CONTACT_DAMPING)
        j_eff = P[I_JM] * P[I_JL] / j
        w = 2.0 * math.pi * f_hz
        P[I_CK] = w * w * j_eff
        P[I_CC] = 2.0 * zeta * math.sqrt(P[I_CK] * j_eff)
        # Explicit coupling: resolve the fastest of the resonance and the damping rate.
        rate = max(w, 2.0 * zeta * w)
        n_sub = max(1, math.ceil(rate * dt_s / MAX_OMEGA_H))
        P[I_TWO] = 1.0
    P[I_NSUB] = float(n_sub)
    start, step, table = generic_torque_table(model, range_rad)
    if table.size == 0:
        return P
    P[I_TAB0], P[I_TABH], P[I_TABN] = start, step, float(table.size)
    return np.concatenate((P, table))


@njit(cache=True, inline="always")
def _table_torque(P: FloatArray, theta: float) -> float:
    """The generic effects' tabulated torque at ``theta`` (0 without a table)."""
    n = int(P[I_TABN])
    if n == 0:
        return 0.0
    x = (theta - P[I_TAB0]) / P[I_TABH]
    if x <= 0.0:
        return float(P[N_PACKED])
    if x >= n - 1:
        return float(P[N_PACKED + n - 1])
    i = int(x)
    f = x - i
    return float((1.0 - f) * P[N_PACKED + i] + f * P[N_PACKED + i + 1])


@njit(cache=True, inline="always")
def _saturated(v: float, lim: float) -> float:
    if v > lim:
        return lim
    if v < -lim:
        return -lim
    return float(v)


@njit(cache=True, inline="always")
def _sample_index(idx: int, n: int) -> int:
    """``idx`` clamped to the log's samples 0..n−1 (the command holds before and after)."""
    if idx < 0:
        return 0
    if idx >= n:
        return n - 1
    return idx


@njit(cache=True, inline="always")
def _delayed_span(t0: float, h: float, dt: float, delay: float) -> tuple[int, bool, float]:
    """Where [t0 − delay, t0 − delay + h] lies in the held command: (first sample j, whether
    it lies within sample j alone, the weight of sample j when it spans j and j + 1)."""
    a = (t0 - delay) / dt
    j = int(math.floor(a + 1e-12))
    frac_end = a + h / dt - j  # where the window ends, in samples from j
    if frac_end <= 1.0 + 1e-12:
        return j, True, 1.0
    return j, False, (1.0 - (a - j)) * dt / h


@njit(cache=True, inline="always")
def _from_rest(net: float, J: float, h: float, fcp: float, fcn: float, stic: float, fs: float) -> float:
    """Velocity after ``h`` from rest under ``net`` torque: Karnopp stick or break-away
    (``stic`` > 0: stiction on, ``fs`` its break-away torque)."""
    fc = fcp if net > 0.0 else fcn
    thr = fc
    if stic > 0.0 and fs > thr:
        thr = fs
    if abs(net) <= thr:
        return 0.0
    s = 1.0 if net > 0.0 else -1.0
    return float(h * (net - s * thr) / J)


@njit(cache=True, inline="always")
def _friction_step(
    omega: float,
    net: float,
    J: float,
    h: float,
    fcp: float,
    fcn: float,
    bp: float,
    bn: float,
    stic: float,
    fs: float,
    vs: float,
) -> float:
    """Advance a velocity by h under ``net`` non-friction torque and Karnopp/Stribeck friction
    (``stic`` > 0: stiction on, with break-away torque ``fs`` and Stribeck velocity ``vs``).

    When friction and the torque bring the axis to rest inside the step, the rest of the step
    is spent at rest or breaking away again (a reversal takes no more time than it should).
    """
    if omega == 0.0:
        return _from_rest(net, J, h, fcp, fcn, stic, fs)
    if omega > 0.0:
        fc, b, s = fcp, bp, 1.0
    else:
        fc, b, s = fcn, bn, -1.0
    fr = fc
    if stic > 0.0:
        x = omega / vs
        fr = fc + (fs - fc) * math.exp(-x * x)
    acc = (net - s * fr - b * omega) / J
    new = omega + h * acc
    if new * omega <= 0.0:
        # At rest after tau = −ω/acc (0 < tau ≤ h); the remaining time from rest.
        tau = -omega / acc
        return _from_rest(net, J, h - tau, fcp, fcn, stic, fs)
    return float(new)


@njit(cache=True, inline="always")
def step_state(
    th_m: float,
    om_m: float,
    th_l: float,
    om_l: float,
    P: FloatArray,
    u: FloatArray,
    k: int,
    dt: float,
    dist_nm: float,
) -> tuple[float, float, float, float]:
    """The state [θ_motor, ω_motor, θ_load, ω_load] advanced from t_k to t_{k+1} under command
    history ``u``.

    ``u[k]`` is the command held over [t_k, t_{k+1}); earlier samples feed the delay.
    ``dist_nm`` is an external torque on the load over the step.

    Hot: the compiled loops call it once a sample per candidate model. The state is passed as
    scalars and ``P`` is read into locals once, so the helpers get floats: with the state in an
    array and ``P``/``u`` handed to every helper, a step took 1.9x as long (numba counts the
    references of array arguments and does not always drop the counting; a caller compiled
    without reference counting, ``measurements/observed.py``, gains another 1.45x).
    """
    n_sub = int(P[I_NSUB])
    h = dt / n_sub
    half_h = 0.5 * h
    lim, delay = P[I_ULIM], P[I_DELAY]
    k_nm, jm = P[I_K], P[I_JM]
    fcp, fcn, bp, bn = P[I_FCP], P[I_FCN], P[I_BP], P[I_BN]
    stic, fs, vs = P[I_STIC], P[I_FS], P[I_VS]
    offset, ra, rn, rph, gt, gph = P[I_OFFSET], P[I_RA], P[I_RN], P[I_RPH], P[I_GT], P[I_GPH]
    has_table = P[I_TABN] != 0.0
    n_u = u.shape[0]
    for i in range(n_sub):
        # Leapfrog: the velocity lives at half steps, so its kick spans [t − h/2, t + h/2].
        # The command may step at t (a sample instant): each half takes its own held command,
        # and friction acts on each half (Karnopp is not linear in the torque).
        if delay == 0.0:  # the common case, without the general averaging
            u_b = _saturated(u[_sample_index(k, n_u)], lim)
            u_a = _saturated(u[_sample_index(k - 1, n_u)], lim) if i == 0 else u_b
        else:
            # The array is indexed here, not in a helper (see above).
            t = k * dt + i * h
            j, single, w1 = _delayed_span(t - half_h, half_h, dt, delay)
            u_a = _saturated(u[_sample_index(j, n_u)], lim)
            if not single:
                u_a = float(w1 * u_a + (1.0 - w1) * _saturated(u[_sample_index(j + 1, n_u)], lim))
            j, single, w1 = _delayed_span(t, half_h, dt, delay)
            u_b = _saturated(u[_sample_index(j, n_u)], lim)
            if not single:
                u_b = float(w1 * u_b + (1.0 - w1) * _saturated(u[_sample_index(j + 1, n_u)], lim))
        if P[I_TWO] == 0.0:
            th = th_m
            rest = -offset + dist_nm - (_table_torque(P, th) if has_table else 0.0)
            if ra != 0.0:
                rest -= ra * math.sin(rn * th + rph)
            if gt != 0.0:
                rest -= gt * math.sin(th + gph)
            if u_a == u_b:
                om_m = _friction_step(om_m, k_nm * u_a + rest, jm, h, fcp, fcn, bp, bn, stic, fs, vs)
            else:
                om_m = _friction_step(om_m, k_nm * u_a + rest, jm, half_h, fcp, fcn, bp, bn, stic, fs, vs)
                om_m = _friction_step(om_m, k_nm * u_b + rest, jm, half_h, fcp, fcn, bp, bn, stic, fs, vs)
            th_m += h * om_m
            th_l = th_m
            om_l = om_m
        else:
            half = 0.5 * P[I_BW]
            delta = th_m - th_l
            if delta > half:
                dz = delta - half
            elif delta < -half:
                dz = delta + half
            else:
                dz = 0.0
            tau_c = P[I_CK] * dz
            if dz != 0.0:
                tau_c += P[I_CC] * (om_m - om_l)
            # Terms of absent effects are skipped, not multiplied by zero (two sines a sub-step).
            rest = -offset
            if ra != 0.0:
                rest -= ra * math.sin(rn * th_m + rph)
            rest -= tau_c
            if has_table:
                rest -= _table_torque(P, th_m)
            if u_a == u_b:
                om_m = _friction_step(om_m, k_nm * u_a + rest, jm, h, fcp, fcn, bp, bn, stic, fs, vs)
            else:
                om_m = _friction_step(om_m, k_nm * u_a + rest, jm, half_h, fcp, fcn, bp, bn, stic, fs, vs)
                om_m = _friction_step(om_m, k_nm * u_b + rest, jm, half_h, fcp, fcn, bp, bn, stic, fs, vs)
            load = tau_c
            if gt != 0.0:
                load -= gt * math.sin(th_l + gph)
            om_l += h * (load + dist_nm) / P[I_JL]
            th_m += h * om_m
            th_l += h * om_l
    return th_m, om_m, th_l, om_l


@njit(cache=True, inline="always")
def advance(x: FloatArray, P: FloatArray, u: FloatArray, k: int, dt: float, dist_nm: float) -> None:
    """Advance state ``x`` (shape (4,), in place) from t_k to t_{k+1}: :func:`step_state`."""
    x[0], x[1], x[2], x[3] = step_state(x[0], x[1], x[2], x[3], P, u, k, dt, dist_nm)


@njit(cache=True, inline="always")
def encoder_rad(x: FloatArray, P: FloatArray) -> float:
    """What the encoder (on the motor) reports for state ``x``."""
    q = P[I_Q]
    if q > 0.0:
        return float(q * math.floor(x[0] / q + 0.5))
    return float(x[0])


@njit(cache=True)
def _run(
    P: FloatArray, u: FloatArray, dt: float, x0: FloatArray, dist: FloatArray
) -> tuple[FloatArray, FloatArray]:
    n = u.shape[0]
    states = np.empty((n, STATE_SIZE))
    meas = np.empty(n)
    x = x0.copy()
    has_dist = dist.shape[0] == n
    for k in range(n):
        states[k, :] = x
        meas[k] = encoder_rad(x, P)
        advance(x, P, u, k, dt, dist[k] if has_dist else 0.0)
    return states, meas


@njit(cache=True)
def _run_windows(
    P: FloatArray, u: FloatArray, dt: float, starts: NDArray[np.int64], horizon: int, x0s: FloatArray
) -> FloatArray:
    m = starts.shape[0]
    out = np.empty((m, horizon))
    x = np.empty(STATE_SIZE)
    for w in range(m):
        x[:] = x0s[w]
        k0 = starts[w]
        for i in range(horizon):
            out[w, i] = x[0]
            advance(x, P, u, k0 + i, dt, 0.0)
    return out


@dataclass(frozen=True, slots=True)
class SimResult:
    """A simulated run: every array has shape (n,), sample k at ``t_s[k]``.

    ``theta_rad`` is what the encoder reports (motor side, quantized when the model has
    ``quantization``); ``load_theta_rad`` is where the load (camera) really points.
    """

    t_s: FloatArray
    u_v: FloatArray
    theta_rad: FloatArray
    omega_rad_s: FloatArray
    load_theta_rad: FloatArray
    load_omega_rad_s: FloatArray


def initial_state(theta_rad: float = 0.0, omega_rad_s: float = 0.0) -> FloatArray:
    """A state with motor and load together (backlash centred). Returns shape (4,)."""
    return np.array([theta_rad, omega_rad_s, theta_rad, omega_rad_s], dtype=float)


def _check_input(u_v: FloatArray, dt_s: float) -> FloatArray:
    u = np.ascontiguousarray(u_v, dtype=float)
    if u.ndim != 1 or u.size == 0:
        raise DataError(f"command must be a non-empty 1-D array, got shape {u.shape}")
    bad = np.flatnonzero(~np.isfinite(u))
    if bad.size:
        raise DataError(f"command sample {bad[0]} is {u[bad[0]]!r}")
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise DataError(f"sample time must be positive, got {dt_s!r}")
    return u


def simulate(
    model: AxisModel,
    u_v: FloatArray,
    dt_s: float,
    x0: FloatArray | None = None,
    disturbance_nm: FloatArray | None = None,
    quantize: bool = True,
) -> SimResult:
    """Simulate ``model`` driven by the command ``u_v`` (V, shape (n,)) sampled every ``dt_s``.

    ``x0`` is the initial state (see :func:`initial_state`); ``disturbance_nm`` an external load
    torque per sample, shape (n,). The drive delivers the command as given (its rail,
    :func:`~tracker.plant.effects.saturation.drive_rail_v`, is never below it); only a
    saturation clips it. Generic effects are tabulated over ±2π around the start angle (see
    :func:`pack_params`). Returns a :class:`SimResult`.
    """
    u = _check_input(u_v, dt_s)
    x = initial_state() if x0 is None else np.asarray(x0, dtype=float)
    P = pack_params(model, dt_s, quantize, (float(x[0]), float(x[0])), drive_rail_v(u))
    dist = np.zeros(0) if disturbance_nm is None else np.ascontiguousarray(disturbance_nm, dtype=float)
    if dist.size and dist.shape != u.shape:
        raise DataError(f"disturbance has shape {dist.shape}, command has {u.shape}")
    states, meas = _run(P, u, float(dt_s), x, dist)
    t = np.arange(u.size, dtype=np.float64) * dt_s
    return SimResult(t, u, meas, states[:, 1], states[:, 2], states[:, 3])


def predict_windows(
    model: AxisModel,
    u_v: FloatArray,
    dt_s: float,
    starts: NDArray[np.int64],
    horizon: int,
    x0s: FloatArray,
) -> FloatArray:
    """Simulate many windows of ``horizon`` samples, window w starting at sample ``starts[w]``
    from state ``x0s[w]`` (shape (m, 4)) under the measured command (delivered as in
    :func:`simulate`). Motor angle, unquantized.

    Returns shape (m, horizon); column 0 is the starting angle. This is the k-step-ahead
    predictor's hot path.
    """
    u = _check_input(u_v, dt_s)
    st = np.ascontiguousarray(starts, dtype=np.int64)
    x0 = np.ascontiguousarray(x0s, dtype=float).reshape(-1, STATE_SIZE)
    span = (float(x0[:, 0].min()), float(x0[:, 0].max())) if x0.size else (0.0, 0.0)
    P = pack_params(model, dt_s, quantize=False, range_rad=span, rail_v=drive_rail_v(u))
    return _run_windows(P, u, float(dt_s), st, int(horizon), x0)


__all__ = [
    "SEED_ENCODER_STEP_RAD",
    "STATE_SIZE",
    "SimResult",
    "advance",
    "encoder_rad",
    "generic_torque_table",
    "initial_state",
    "pack_params",
    "predict_windows",
    "simulate",
    "step_state",
]
