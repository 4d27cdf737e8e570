"""Plant physics of a geared DC-motor axis, written independently of `tracker/`.

Everything is in load coordinates (angles and torques seen at the output shaft): the motor's
angle is θm = (motor shaft angle)/N, its inertia N²·J_rotor, its torque N·Kt·i.

State vector x (shape (7,)):
    0 i_a      armature current (A)
    1 th_m     motor side angle (rad, load coordinates)
    2 w_m      motor side speed (rad/s)
    3 th_l     load angle (rad; = th_m on a rigid axis)
    4 w_l      load speed (rad/s)
    5 z_m      LuGre bristle deflection, motor side (rad)
    6 z_l      LuGre bristle deflection, load side (rad)

Electrics:  L di/dt = V_amp − R i − Ke·N·w_m,  V_amp = clip(G_amp·u_applied, ±V_rail).
Mechanics (rigid):  J w' = N Kt i − F_m(w) − F_l(w) − cog(th) − grav(th) − bias − d(t).
Two-mass: the motor side carries F_m and the cogging, the load side F_l, gravity, the bias
and the disturbance; they are joined by a belt (spring-damper) or a gear with a dead band.

Friction law per side: Coulomb level per direction with a Stribeck bump to the static level,
viscous per direction; as a smooth-but-stiff tanh law or as a LuGre bristle model.
The integrator is a fixed-step RK4 (numba), many sub-steps per log sample.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# indices into the packed parameter vector p
P_R_OHM, P_L_H, P_KT, P_KE, P_N, P_GAMP, P_VRAIL = 0, 1, 2, 3, 4, 5, 6
P_JM, P_JL, P_MODE, P_K_NM_RAD, P_C_NMS_RAD, P_GAP_RAD = 7, 8, 9, 10, 11, 12
P_GRAV_NM, P_GRAV_PHASE, P_BIAS_NM, P_COG_NM, P_COG_CYC, P_COG_PHASE = 13, 14, 15, 16, 17, 18
P_LAW = 19
# per side friction block: base index 20 (motor), 30 (load)
F_FC_POS, F_FC_NEG, F_FS, F_VS, F_B_POS, F_B_NEG, F_VEPS, F_SIGMA0, F_SIGMA1, F_VD = range(10)
P_FRIC_M, P_FRIC_L = 20, 30
N_PARAMS = 40

MODE_RIGID, MODE_BELT, MODE_BACKLASH = 0, 1, 2
LAW_TANH, LAW_LUGRE = 0, 1
N_STATE = 7


@numba.njit(cache=True)
def _g_level(p: np.ndarray, base: int, w: float) -> float:
    """Stribeck level: Coulomb of the direction plus the static bump (N·m)."""
    fc = p[base + F_FC_POS] if w >= 0.0 else p[base + F_FC_NEG]
    vs = p[base + F_VS]
    bump = (p[base + F_FS] - fc) * math.exp(-((w / vs) ** 2)) if vs > 0.0 else 0.0
    return fc + bump


@numba.njit(cache=True)
def _viscous(p: np.ndarray, base: int, w: float) -> float:
    return (p[base + F_B_POS] if w >= 0.0 else p[base + F_B_NEG]) * w


@numba.njit(cache=True)
def friction_nm(p: np.ndarray, base: int, w: float, z: float) -> tuple[float, float]:
    """Friction torque of one side and dz/dt of its bristles."""
    if p[P_LAW] == LAW_LUGRE:
        g = max(_g_level(p, base, w), 1e-9)
        sigma0 = p[base + F_SIGMA0]
        dz = w - sigma0 * abs(w) * z / g
        sigma1 = p[base + F_SIGMA1] * math.exp(-((w / p[base + F_VD]) ** 2))
        return sigma0 * z + sigma1 * dz + _viscous(p, base, w), dz
    return _g_level(p, base, w) * math.tanh(w / p[base + F_VEPS]) + _viscous(p, base, w), 0.0


@numba.njit(cache=True)
def derivative(x: np.ndarray, p: np.ndarray, u_applied_v: float, dist_nm: float) -> np.ndarray:
    """dx/dt for the state layout above."""
    dx = np.zeros(N_STATE)
    n = p[P_N]
    v_amp = min(max(p[P_GAMP] * u_applied_v, -p[P_VRAIL]), p[P_VRAIL])
    dx[0] = (v_amp - p[P_R_OHM] * x[0] - p[P_KE] * n * x[2]) / p[P_L_H]
    tau_motor = n * p[P_KT] * x[0]
    cog = p[P_COG_NM] * math.sin(p[P_COG_CYC] * x[1] + p[P_COG_PHASE])
    fm, dzm = friction_nm(p, P_FRIC_M, x[2], x[5])
    mode = p[P_MODE]
    th_l = x[1] if mode == MODE_RIGID else x[3]
    w_l = x[2] if mode == MODE_RIGID else x[4]
    fl, dzl = friction_nm(p, P_FRIC_L, w_l, x[6])
    load_side = fl + p[P_GRAV_NM] * math.sin(th_l + p[P_GRAV_PHASE]) + p[P_BIAS_NM] + dist_nm
    dx[5] = dzm
    dx[6] = dzl
    if mode == MODE_RIGID:
        dx[1] = x[2]
        dx[2] = (tau_motor - fm - cog - load_side) / (p[P_JM] + p[P_JL])
        return dx
    twist = x[1] - x[3]
    twist_rate = x[2] - x[4]
    if mode == MODE_BELT:
        coupling = p[P_K_NM_RAD] * twist + p[P_C_NMS_RAD] * twist_rate
    else:
        half = 0.5 * p[P_GAP_RAD]
        coupling = 0.0
        if twist > half:
            coupling = max(p[P_K_NM_RAD] * (twist - half) + p[P_C_NMS_RAD] * twist_rate, 0.0)
        elif twist < -half:
            coupling = min(p[P_K_NM_RAD] * (twist + half) + p[P_C_NMS_RAD] * twist_rate, 0.0)
    dx[1] = x[2]
    dx[2] = (tau_motor - fm - cog - coupling) / p[P_JM]
    dx[3] = x[4]
    dx[4] = (coupling - load_side) / p[P_JL]
    return dx


@numba.njit(cache=True)
def advance(
    x: np.ndarray,
    p: np.ndarray,
    u_before_v: float,
    u_after_v: float,
    switch_frac: float,
    dist0_nm: float,
    dist1_nm: float,
    period_s: float,
    n_sub: int,
) -> np.ndarray:
    """Integrate one log period with RK4 in n_sub steps.

    The applied command is u_before_v until switch_frac·period_s, u_after_v after (a transport
    delay that is not a whole number of periods); the disturbance is linear between its two
    sample values. Returns the new state (the input is not changed).
    """
    h = period_s / n_sub
    y = x.copy()
    for k in range(n_sub):
        t0 = k * h
        u = u_before_v if t0 + 0.5 * h <= switch_frac * period_s else u_after_v
        d_a = dist0_nm + (dist1_nm - dist0_nm) * (t0 / period_s)
        d_m = dist0_nm + (dist1_nm - dist0_nm) * ((t0 + 0.5 * h) / period_s)
        d_b = dist0_nm + (dist1_nm - dist0_nm) * ((t0 + h) / period_s)
        k1 = derivative(y, p, u, d_a)
        k2 = derivative(y + 0.5 * h * k1, p, u, d_m)
        k3 = derivative(y + 0.5 * h * k2, p, u, d_m)
        k4 = derivative(y + h * k3, p, u, d_b)
        y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return y


def substeps_for(period_s: float, max_step_s: float = 10e-6) -> int:
    """At least 20 RK4 steps per log period and none longer than max_step_s."""
    return max(20, math.ceil(period_s / max_step_s))
