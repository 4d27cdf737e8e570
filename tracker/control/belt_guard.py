"""The soft-limit guard for a belt-driven axis: a two-mass observer, a latching backup, a trigger.

Used by :func:`tracker.control.loop.controller_step` instead of the rigid
:func:`tracker.control.limits.guard_command` when the design model has ``compliance``. The
encoder is on the motor; the camera is on the load, behind the belt (see
:mod:`tracker.plant.simulate`: a share ``inertia.motor_fraction`` of J on the motor side)::

    Jm θm'' = K u − b θm' − k (θm − θl) − c (θm' − θl') + d,    Jl θl'' = k (θm − θl) + c (θm' − θl')

with ``d`` a lumped, slowly varying motor-side torque (friction, offset...).

1. **Observer**: the model above, zero-order-hold discretised, states [θm, ωm, θl, ωl, d],
   corrected every sample by the encoder (steady-state Kalman gain, current form).
2. **Backup**: a discrete LQR with integral action on the load angle (LQI) that holds the
   load at a point ``p`` and damps the belt; its command is capped at ``BACKUP_LIMIT_V``
   (the lowest amplifier clip the guard assumes), so what it asks is what any rig within the
   assumptions delivers. The integrator removes a constant hidden torque's offset.
3. **Trigger**: every sample, the controller's command is accepted only if the model predicts
   that this command, followed from the next sample by the backup (holding the load where it
   then is), keeps the load inside the guard line. The prediction carries the observer's
   torque estimate d̂ as a constant and delays every command by the model's delay plus
   ``HIDDEN_DELAY_S``. When the check fails the backup **latches**: it takes over completely
   from the (possibly destabilising) controller for at least ``RELEASE_S`` (time to damp the
   belt), and then until the observed motor and load are calm (``RELEASE_RAD_S``) and the
   controller's command passes the check again.

This module is the compiled runtime; :mod:`tracker.control.belt_guard_design` designs and packs
it (``BACKUP_LIMIT_V``, ``HIDDEN_DELAY_S`` and the weights live there). What this can
guarantee is what the model says: ``belt_guard_design.backup_spectral_radius`` checks the
backup's loop against gain, delay and belt-frequency errors; the limits of the guarantee are in
:mod:`tracker.control.limits` and docs/control.md.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# Uncertainty of the observer's torque estimate d̂ the prediction allows for (N·m), and how
# long a command's excess over the backup limit may linger in d̂ (s).
DIST_MARGIN_NM = 0.03
EXCESS_FADE_S = 0.05
# Prediction horizon, and how often (samples) it tries to end early with the certificate.
HORIZON_S = 1.5
CERT_EVERY = 4
# The backup holds for at least this long before the controller may take over again.
RELEASE_S = 0.2
# ... and until both observed velocities are below this (a release on a swinging estimate, with
# the belt 10 % off the model's, let the controller push the load past: bench_limits_belt.py).
RELEASE_RAD_S = 0.5
# Longest command history kept (samples): known plus hidden delay must fit.
MAX_DELAY_SAMPLES = 12


# Packed layout (offsets inside the guard's parameter slice; literal indices for numba's cache).
G_A, G_B, G_L, G_K, G_ND, G_NP, G_UB, G_DT, G_LO, G_HI, G_PLO, G_PHI = (
    0,
    25,
    30,
    35,
    40,
    41,
    42,
    43,
    44,
    45,
    46,
    47,
)
G_N, G_PIL, G_PIU, G_INVK, G_P = 48, 49, 50, 51, 52  # certificate: size, (P⁻¹)₂₂, (P⁻¹)ₙₙ, 1/K, P
N_CERT = 6 + MAX_DELAY_SAMPLES
N_GP = G_P + N_CERT * N_CERT
# Guard state slice: observer [5], latch flag, hold point, integral, time latched, recent
# command excess over the backup limit (V), started flag, command history (newest last).
B_X, B_LATCH, B_P, B_I, B_T, B_EX, B_ON, B_H = 0, 5, 6, 7, 8, 9, 10, 11
N_GS = B_H + MAX_DELAY_SAMPLES


@njit(cache=True)
def _step_model(gp: FloatArray, x: FloatArray, d: float, u: float) -> None:
    """x (4,) ← A₄ x + A[:, d] d + B u, the model's mechanical states over one sample."""
    y0 = gp[0] * x[0] + gp[1] * x[1] + gp[2] * x[2] + gp[3] * x[3] + gp[4] * d + gp[25] * u
    y1 = gp[5] * x[0] + gp[6] * x[1] + gp[7] * x[2] + gp[8] * x[3] + gp[9] * d + gp[26] * u
    y2 = gp[10] * x[0] + gp[11] * x[1] + gp[12] * x[2] + gp[13] * x[3] + gp[14] * d + gp[27] * u
    y3 = gp[15] * x[0] + gp[16] * x[1] + gp[17] * x[2] + gp[18] * x[3] + gp[19] * d + gp[28] * u
    x[0], x[1], x[2], x[3] = y0, y1, y2, y3


@njit(cache=True)
def _backup(gp: FloatArray, x: FloatArray, integ: float, p: float) -> float:
    u = -(gp[35] * (x[0] - p) + gp[36] * x[1] + gp[37] * (x[2] - p) + gp[38] * x[3] + gp[39] * integ)
    ub = gp[42]
    return float(min(max(u, -ub), ub))


@njit(cache=True)
def _hold_point(gp: FloatArray, theta_l: float) -> float:
    return float(min(max(theta_l, gp[46]), gp[47]))


@njit(cache=True)
def _keeps_inside_under(gp: FloatArray, gs: FloatArray, u_v: float, d: float) -> bool:
    """The prediction of :func:`backup_keeps_inside` under one constant motor-side torque ``d``."""
    x = np.empty(4)
    x[0], x[1], x[2], x[3] = gs[0], gs[1], gs[2], gs[3]
    nd = int(gp[41])
    dt = gp[43]
    lo, hi, ub = gp[44], gp[45], gp[42]
    n_hist = gs.shape[0] - 11
    queue = np.empty(nd + 1)  # commands in flight, at most what every rig delivers; [0] acts next
    for i in range(nd):
        queue[i] = min(max(gs[11 + n_hist - nd + i], -ub), ub)
    queue[nd] = min(max(u_v, -ub), ub)
    p = 0.0
    integ = 0.0
    n = int(HORIZON_S / dt)
    for j in range(n):
        _step_model(gp, x, d, queue[0])
        if x[2] > hi or x[2] < lo:
            return False
        if j == 0:
            p = _hold_point(gp, x[2])
        u = _backup(gp, x, integ, p)
        integ += dt * (x[2] - p)
        for i in range(nd):
            queue[i] = queue[i + 1]
        queue[nd] = u
        if j % CERT_EVERY == 0 and _certified(gp, x, integ, queue, d, p):
            return True
    return False


@njit(cache=True)
def backup_keeps_inside(gp: FloatArray, gs: FloatArray, u_v: float) -> bool:
    """Does ``u_v`` now, then the backup from the next sample, keep the model's load inside?

    Starts from the corrected observer state in ``gs``; commands reach the model
    ``G_NP`` samples late (past ones from the history), clipped at ``BACKUP_LIMIT_V``. The
    observer's torque estimate d̂ is uncertain by ``DIST_MARGIN_NM`` plus what a lower
    amplifier clip may have hidden in it (K times the recent command excess over the backup
    limit); the prediction must hold at both ends d̂ ± Δ. False when the load crosses a line or
    the backup has not provably settled within the horizon.
    """
    k_nm_per_v = 1.0 / gp[51]
    excess = max(gs[9], abs(u_v) - gp[42], 0.0)
    spread = DIST_MARGIN_NM + k_nm_per_v * excess
    d = gs[4]
    return _keeps_inside_under(gp, gs, u_v, d + spread) and _keeps_inside_under(gp, gs, u_v, d - spread)


@njit(cache=True)
def _certified(gp: FloatArray, x: FloatArray, integ: float, queue: FloatArray, d: float, p: float) -> bool:
    """True if the linear backup loop, from here on, provably stays inside and unsaturated."""
    n = int(gp[48])
    u_eq = -d * gp[51]
    ub = gp[42]
    if abs(u_eq) >= ub:
        return False
    e = np.empty(n)
    e[0], e[1], e[2], e[3] = x[0] - p, x[1], x[2] - p, x[3]
    e[4] = integ + u_eq / gp[39]  # at equilibrium −g₄·∫ = u_eq
    for i in range(n - 5):
        e[5 + i] = queue[i] - u_eq
    c = 0.0
    for i in range(n):
        row = 0.0
        for k in range(n):
            row += gp[52 + i * n + k] * e[k]
        c += e[i] * row
    reach = math.sqrt(c * gp[49])
    if p + reach > gp[45] or p - reach < gp[44]:
        return False
    return bool(abs(u_eq) + math.sqrt(c * gp[50]) <= ub)


@njit(cache=True)
def belt_guard_command(gp: FloatArray, gs: FloatArray, y_rad: float, u_v: float, u_max_v: float) -> float:
    """One sample of the belt guard: encoder ``y_rad`` and the controller's ``u_v`` in, volts out.

    Updates the observer, the latch and the command history in ``gs`` (shape (N_GS,)).
    A fresh ``gs`` (all zeros) starts itself at rest at the encoder angle; see
    :func:`reset_belt_guard`.
    """
    if gs[10] == 0.0:
        reset_belt_guard(gs, y_rad, 0.0)
    if u_v != u_v:
        u_v = 0.0
    u_v = min(max(u_v, -u_max_v), u_max_v)
    n_hist = gs.shape[0] - 11
    nd = int(gp[40])
    # Observer correction (current form); the model's own delay applies to the commands.
    innov = y_rad - gs[0]
    for i in range(5):
        gs[i] += gp[30 + i] * innov
    x = gs[0:4]
    dt = gp[43]
    latched = gs[5] > 0.0
    calm = abs(x[1]) < RELEASE_RAD_S and abs(x[3]) < RELEASE_RAD_S
    if latched and gs[8] >= RELEASE_S and calm and backup_keeps_inside(gp, gs, u_v):
        latched = False  # held long enough, and the controller's command is safe again
        gs[5] = 0.0
    if latched:
        u = _backup(gp, x, gs[7], gs[6])
        gs[7] += dt * (x[2] - gs[6])
        gs[8] += dt
    elif backup_keeps_inside(gp, gs, u_v):
        u = u_v
    else:
        gs[5] = 1.0
        gs[6] = _hold_point(gp, x[2])
        gs[7] = 0.0
        gs[8] = 0.0
        u = _backup(gp, x, 0.0, gs[6])
    # The command's excess over the backup limit fades from d̂ with the observer (EXCESS_FADE_S).
    gs[9] = max(abs(u) - gp[42], gs[9] * (1.0 - dt / EXCESS_FADE_S), 0.0)
    # History of applied commands (newest last), then the observer's prediction.
    for i in range(n_hist - 1):
        gs[11 + i] = gs[12 + i]
    gs[11 + n_hist - 1] = u
    u_obs = gs[11 + n_hist - 1 - nd]
    xs = np.empty(4)
    xs[0], xs[1], xs[2], xs[3] = gs[0], gs[1], gs[2], gs[3]
    _step_model(gp, xs, gs[4], u_obs)
    gs[0], gs[1], gs[2], gs[3] = xs[0], xs[1], xs[2], xs[3]
    return float(u)


@njit(cache=True)
def reset_belt_guard(gs: FloatArray, y_rad: float, omega_rad_s: float) -> None:
    """Start the guard with motor and load together at the encoder angle and ``omega_rad_s``,
    no latch, no history (a guard switched on mid-run, by a new model, starts from the motion)."""
    gs[:] = 0.0
    gs[0] = y_rad
    gs[1] = omega_rad_s
    gs[2] = y_rad
    gs[3] = omega_rad_s
    gs[10] = 1.0
