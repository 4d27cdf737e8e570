"""The discrete controller of one axis, compiled: observer, shaping, 2-DOF law, anti-windup, guard.

Every sample k (Ts = 1 ms) :func:`controller_step` takes the encoder angle yₖ and the target
and returns the command uₖ (V), held over [tₖ, tₖ₊₁):

1. clamp the target into the soft limits and shape it (rate/acceleration limits) into a
   reference r, r', r'' (:mod:`tracker.control.trajectory`);
2. correct the observer with yₖ (:mod:`tracker.control.observer`): θ̂, ω̂;
3. law "observer_pd_ff": u = (J r'' + b r' + τ_static(r) + Fc·s)/K + Kp (r − θ̂) + Kd (r' − ω̂)
   + Ki ∫(r − θ̂) − g·(d̂/K + Fc·s/K), where τ_static is the model's offset and gravity
   T·sin(r + φ) (zero unless a fitted model has them), g the fraction of the observer's
   residual disturbance torque d̂ cancelled (0 by default),
   s = tanh(v/v_band) the smoothed friction sign, v = r' while the reference moves and the
   *observed* velocity ω̂ otherwise; the integrator stops while the command is saturated and its
   share is capped (anti-windup);
   law "seed_lead": u = C(z)(r − y), the seed's first-order lead on the raw encoder error;
4. the soft-limit guard (:mod:`tracker.control.limits`) on its own fixed observer of the rated
   axis, counting on the braking envelope rather than the model
   (:mod:`tracker.control.envelope`), then the ±10 V clip;
5. the observer predicts the next sample with the applied command.

Parameters travel as one packed float vector (``CP``), state as another (``CS``), so the whole
loop compiles with numba next to the plant (:mod:`tracker.control.closed_loop`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.control.belt_guard import (
    B_ON,
    G_PHI,
    G_PLO,
    N_GP,
    N_GS,
    belt_guard_command,
    reset_belt_guard,
)
from tracker.control.belt_guard_design import design_belt_guard, pack_belt_guard
from tracker.control.envelope import (
    MEASURE_WINDOW_S,
    N_ES,
    BrakingEnvelope,
    counted_decel,
    guard_figures,
    measure_full_command,
)
from tracker.control.gains import ControllerGains, LeadGains, ObserverPdGains
from tracker.control.limits import (
    GUARD_LATENCY_S,
    GUARD_OBSERVER_HZ,
    SoftLimits,
    belt_guard_lines,
    clamp_target,
    guard_command_held,
    held_speed,
)
from tracker.control.observer import design_observer
from tracker.control.trajectory import TrajectoryLimits, shape_step
from tracker.plant.model import AxisModel
from tracker.units import AMPLIFIER_LIMIT_V

FloatArray = NDArray[np.float64]

KIND_LEAD, KIND_PD = 0.0, 1.0
# Packed controller parameters (literal indices keep numba's cache honest).
C_KIND, C_DT, C_LG, C_LZ, C_LP = 0, 1, 2, 3, 4
C_KP, C_KD, C_KI, C_ILIM, C_FJ, C_FB, C_FCP, C_FCN, C_BAND, C_FSCALE, C_VSRC = (
    5,
    6,
    7,
    8,
    9,
    10,
    11,
    12,
    13,
    14,
    15,
)
C_A, C_B, C_L = 16, 25, 28  # observer A (3x3 row-major), B (3), L (3)
C_VMAX, C_AMAX, C_SHAPE = 31, 32, 33
C_LO, C_HI, C_TMARG, C_GMARG, C_DECEL, C_LAT, C_UMAX, C_FF = 34, 35, 36, 37, 38, 39, 40, 41
C_GA, C_GB, C_GL = 42, 51, 54  # the guard's own observer (fixed bandwidth, not a tunable gain)
C_KJ = 57  # K/J, rad/s² per V, for the guard's worst case
C_DOB, C_INVK = 58, 59  # disturbance compensation gain, 1/K (V per N·m)
C_ADAPT = 60  # Coulomb adaptation rate (1/s)
C_OFF, C_GT, C_GPH = 61, 62, 63  # the model's static torques, in V: offset, gravity amplitude, phase
C_BELT = 64  # 1: the model has a belt; the two-mass guard (belt_guard.py) replaces the rigid one
C_BGP = 65  # the belt guard's parameters, N_GP of them
# Full-command measurement (envelope.measure_full_command): samples to let it act, window samples.
C_MSET = C_BGP + N_GP
C_MWIN = C_MSET + 1
C_REACH = C_MWIN + 1  # how fast (rad/s per sample) the rigid guard's held speeds may fall
N_CP = C_REACH + 1
# The rigid guard's reach: the outward speed it brakes for falls no faster than this multiple of
# the full command's acceleration K·u_max/J (what the full brake plus hidden torques of up to
# half the torque can do to the axis), so a belt swinging the motor slower for a moment does not
# hide how fast the load still moves.
REACH_DECEL_FACTOR = 1.5
# Adapt only while reference and axis both move faster than this many friction bands.
ADAPT_BANDS = 5.0
# Adapted Coulomb stays within [0, ADAPT_MAX_FACTOR × the model's].
ADAPT_MAX_FACTOR = 4.0
# Controller state.
S_X, S_INT, S_PREVY, S_LE, S_LU, S_REF, S_PREVT, S_INIT, S_TH, S_OM, S_GUARD, S_U = (
    0,
    3,
    4,
    5,
    6,
    7,
    10,
    11,
    12,
    13,
    14,
    15,
)
S_GX = 16
S_FCP, S_FCN = 19, 20  # adapted Coulomb feedforward (V), positive and negative direction
S_BGS = 21  # the belt guard's state, N_GS of them
S_ES = S_BGS + N_GS  # the braking measurement's state, N_ES of them
S_REACH = S_ES + N_ES  # the rigid guard's held outward speeds (rad/s): toward hi (≥ 0), toward lo (≤ 0)
N_CS = S_REACH + 2

VELOCITY_OBSERVER, VELOCITY_DIFFERENCE = 0.0, 1.0


def pack_controller(
    model: AxisModel,
    gains: ControllerGains,
    dt_s: float,
    limits: SoftLimits,
    shaping: TrajectoryLimits | None,
    velocity_source: float = VELOCITY_OBSERVER,
    envelope: BrakingEnvelope | None = None,
) -> FloatArray:
    """Pack ``gains`` designed on ``model`` into the compiled controller's vector, shape (N_CP,).

    ``shaping=None`` passes targets unshaped (the seed's structure). ``envelope`` is the axis's
    rated braking (:mod:`tracker.control.envelope`), which the rigid guard trusts over the
    model; None trusts the model (design studies on a known twin; the engine always passes one).
    """
    p = model.params
    k = model.gain_nm_per_v
    cp = np.zeros(N_CP)
    cp[C_DT] = dt_s
    if isinstance(gains, LeadGains):
        cp[C_KIND] = KIND_LEAD
        cp[C_LG], cp[C_LZ], cp[C_LP] = gains.gain_v_per_rad, gains.zero, gains.pole
        obs_bw = 30.0  # the guard still needs an observed velocity
    else:
        assert isinstance(gains, ObserverPdGains)
        cp[C_KIND] = KIND_PD
        cp[C_KP], cp[C_KD], cp[C_KI] = gains.kp_v_per_rad, gains.kd_v_s_per_rad, gains.ki_v_per_rad_s
        cp[C_ILIM] = gains.integral_limit_v
        cp[C_FF] = gains.feedforward
        cp[C_DOB] = gains.disturbance_comp
        cp[C_ADAPT] = gains.friction_adapt_per_s
        # Static torques the model knows (a fitted model may have them; the seed's has none).
        cp[C_OFF] = p.get("offset.torque", 0.0) / k
        cp[C_GT] = p.get("gravity.torque", 0.0) / k
        cp[C_GPH] = p.get("gravity.phase", 0.0)
        cp[C_FJ] = p["inertia.J"] / k
        cp[C_FB] = p["viscous.b"] / k
        cp[C_FCP] = p["coulomb.torque"] / k
        cp[C_FCN] = p.get("coulomb_asymmetry.negative", p["coulomb.torque"]) / k
        cp[C_BAND] = gains.friction_band_rad_s
        cp[C_FSCALE] = gains.friction_comp
        obs_bw = gains.observer_bandwidth_hz
    cp[C_VSRC] = velocity_source
    obs = design_observer(model, obs_bw, dt_s)
    cp[C_A : C_A + 9] = obs.a.reshape(-1)
    cp[C_B : C_B + 3] = obs.b
    cp[C_L : C_L + 3] = obs.l
    env = envelope if envelope is not None else BrakingEnvelope.of_model(model)
    guard_obs = design_observer(env.observer_model(), GUARD_OBSERVER_HZ, dt_s)
    cp[C_GA : C_GA + 9] = guard_obs.a.reshape(-1)
    cp[C_GB : C_GB + 3] = guard_obs.b
    cp[C_GL : C_GL + 3] = guard_obs.l
    if shaping is not None:
        cp[C_VMAX], cp[C_AMAX], cp[C_SHAPE] = shaping.rate_rad_s, shaping.accel_rad_s2, 1.0
    else:
        cp[C_VMAX], cp[C_AMAX] = 1e9, 1e12
    cp[C_LO], cp[C_HI] = limits.lower_rad, limits.upper_rad
    cp[C_TMARG], cp[C_GMARG] = limits.target_line_margin_rad, limits.guard_margin_rad
    figures = guard_figures(env, model, AMPLIFIER_LIMIT_V)
    cp[C_DECEL], cp[C_KJ] = figures.brake_decel_rad_s2, figures.push_accel_per_v
    cp[C_LAT] = GUARD_LATENCY_S + p.get("delay.seconds", 0.0)
    cp[C_UMAX] = AMPLIFIER_LIMIT_V
    cp[C_MSET] = math.ceil(cp[C_LAT] / dt_s) + 1.0
    cp[C_MWIN] = max(1.0, round(MEASURE_WINDOW_S / dt_s))
    cp[C_REACH] = REACH_DECEL_FACTOR * figures.push_accel_per_v * AMPLIFIER_LIMIT_V * dt_s
    cp[C_INVK] = 1.0 / k
    if model.has("compliance"):
        # The belt guard keeps the load inside lines the twist margin moves in; targets and the
        # shaper then work within the band where the backup holds (HOLD_MARGIN_RAD inside).
        lo_line, hi_line = belt_guard_lines(model, limits)
        cp[C_BELT] = 1.0
        cp[C_BGP : C_BGP + N_GP] = pack_belt_guard(design_belt_guard(model, dt_s), lo_line, hi_line)
        cp[C_LO], cp[C_HI] = cp[C_BGP + G_PLO], cp[C_BGP + G_PHI]
        cp[C_TMARG] = limits.target_margin_rad  # the hold band already lies inside the lines
    return cp


def new_state() -> FloatArray:
    """A fresh controller state (it initialises itself on the first sample). Shape (N_CS,)."""
    return np.zeros(N_CS)


@njit(cache=True, inline="always")
def _clip(x: float, lim: float) -> float:
    if x > lim:
        return lim
    if x < -lim:
        return -lim
    return x


@njit(cache=True, inline="always")
def _predict(a: FloatArray, b: FloatArray, x: FloatArray, th: float, om: float, d: float, u: float) -> None:
    x[0] = a[0] * th + a[1] * om + a[2] * d + b[0] * u
    x[1] = a[3] * th + a[4] * om + a[5] * d + b[1] * u
    x[2] = a[6] * th + a[7] * om + a[8] * d + b[2] * u


@njit(cache=True)
def controller_step(cp: FloatArray, cs: FloatArray, y_rad: float, target_rad: float) -> float:
    """One sample of the controller: encoder ``y_rad`` and ``target_rad`` in, command (V) out."""
    dt = cp[C_DT]
    umax = cp[C_UMAX]
    if cs[S_INIT] == 0.0:
        cs[S_X] = y_rad
        cs[S_X + 1] = 0.0
        cs[S_X + 2] = 0.0
        cs[S_REF] = y_rad
        cs[S_REF + 1] = 0.0
        cs[S_REF + 2] = 0.0
        cs[S_PREVT] = clamp_target(target_rad, cp[C_LO], cp[C_HI], cp[C_TMARG])
        cs[S_PREVY] = y_rad
        cs[S_GX] = y_rad
        cs[S_GX + 1] = 0.0
        cs[S_GX + 2] = 0.0
        cs[S_FCP] = cp[C_FCP]
        cs[S_FCN] = cp[C_FCN]
        cs[S_BGS + B_ON] = 0.0  # the belt guard restarts with the controller
        cs[S_INIT] = 1.0
    # 1. target → shaped reference.
    r = clamp_target(target_rad, cp[C_LO], cp[C_HI], cp[C_TMARG])
    vt = (r - cs[S_PREVT]) / dt
    cs[S_PREVT] = r
    if abs(vt) > cp[C_VMAX]:
        vt = 0.0  # a jump, not a motion: shape it as a step
    if cp[C_SHAPE] > 0.0:
        shape_step(cs[S_REF : S_REF + 3], r, vt, cp[C_VMAX], cp[C_AMAX], dt, cp[C_LO], cp[C_HI])
    else:
        cs[S_REF] = r
        cs[S_REF + 2] = (vt - cs[S_REF + 1]) / dt
        cs[S_REF + 1] = vt
    ref_p = cs[S_REF]
    ref_v = cs[S_REF + 1]
    ref_a = cs[S_REF + 2]
    # 2. observer correction (current form).
    innov = y_rad - cs[S_X]
    th = cs[S_X] + cp[C_L] * innov
    om = cs[S_X + 1] + cp[C_L + 1] * innov
    dist = cs[S_X + 2] + cp[C_L + 2] * innov
    # 3. control law.
    if cp[C_KIND] == KIND_LEAD:
        e = ref_p - y_rad
        u = cp[C_LG] * e - cp[C_LG] * cp[C_LZ] * cs[S_LE] + cp[C_LP] * cs[S_LU]
        cs[S_LE] = e
        cs[S_LU] = u
    else:
        om_fb = om
        if cp[C_VSRC] == VELOCITY_DIFFERENCE:
            om_fb = (y_rad - cs[S_PREVY]) / dt
        e = ref_p - th
        band = cp[C_BAND]
        if abs(ref_v) > band:
            s = math.tanh(ref_v / band)  # the reference moves: feedforward its friction
        else:
            # At rest or creeping: compensate only motion the observer is sure of (beyond a
            # dead zone of 2 bands), so estimation noise cannot excite a stick-slip hunt.
            excess = abs(om_fb) - 2.0 * band
            s = math.tanh(excess / band) if excess > 0.0 else 0.0
            if om_fb < 0.0:
                s = -s
        fc = cs[S_FCP] if s > 0.0 else cs[S_FCN]
        u_fric = cp[C_FSCALE] * fc * s
        moving = abs(ref_v) > ADAPT_BANDS * band and om * ref_v > 0.0 and abs(om) > ADAPT_BANDS * band
        if cp[C_ADAPT] > 0.0 and moving:
            # The observer's torque estimate d̂ is −(true friction) while moving; what the
            # feedforward leaves over, r = d̂/K + u_fric, says how wrong the Coulomb value is.
            # (Inertia and gravity errors average out over a motion; friction's sign does not.)
            resid = dist * cp[C_INVK] + u_fric
            if s > 0.0:
                cs[S_FCP] = min(max(cs[S_FCP] - cp[C_ADAPT] * dt * resid, 0.0), ADAPT_MAX_FACTOR * cp[C_FCP])
            else:
                cs[S_FCN] = min(max(cs[S_FCN] + cp[C_ADAPT] * dt * resid, 0.0), ADAPT_MAX_FACTOR * cp[C_FCN])
        u_static = cp[C_OFF] + cp[C_GT] * math.sin(ref_p + cp[C_GPH])
        u_ff = cp[C_FF] * (cp[C_FJ] * ref_a + cp[C_FB] * ref_v + u_static) + u_fric
        u_i = cp[C_KI] * cs[S_INT]
        # Disturbance compensation: cancel what the observer's torque estimate says the
        # friction feedforward has not already cancelled, capped like the integrator.
        u_d = -cp[C_DOB] * (dist * cp[C_INVK] + u_fric)
        u_d = _clip(u_d, cp[C_ILIM])
        u = u_ff + cp[C_KP] * e + cp[C_KD] * (ref_v - om_fb) + u_i + u_d
        # Anti-windup: integrate only while the command is not pushed further into saturation.
        if not ((u > umax and e > 0.0) or (u < -umax and e < 0.0)):
            cs[S_INT] += e * dt
            if cp[C_KI] != 0.0:
                cs[S_INT] = _clip(cs[S_INT], cp[C_ILIM] / abs(cp[C_KI]))
    # 4. the last line, on its own observer (no gain can blind it), then the amplifier's range.
    g_innov = y_rad - cs[S_GX]
    g_th = cs[S_GX] + cp[C_GL] * g_innov
    g_om = cs[S_GX + 1] + cp[C_GL + 1] * g_innov
    g_d = cs[S_GX + 2] + cp[C_GL + 2] * g_innov
    v_diff = (y_rad - cs[S_PREVY]) / dt
    if cp[C_BELT] > 0.0:
        if cs[S_BGS + B_ON] == 0.0:  # first sample, or a belt model set mid-run: start from the motion
            reset_belt_guard(cs[S_BGS : S_BGS + N_GS], y_rad, g_om)
        ug = belt_guard_command(cp[C_BGP : C_BGP + N_GP], cs[S_BGS : S_BGS + N_GS], y_rad, u, umax)
    else:
        reach_hi = held_speed(cs[S_REACH], max(g_om, v_diff), cp[C_REACH])
        reach_lo = -held_speed(-cs[S_REACH + 1], -min(g_om, v_diff), cp[C_REACH])
        cs[S_REACH], cs[S_REACH + 1] = reach_hi, reach_lo
        ug = guard_command_held(
            u,
            g_th,
            g_om,
            y_rad,
            v_diff,
            reach_hi,
            reach_lo,
            cp[C_LO],
            cp[C_HI],
            cp[C_GMARG],
            counted_decel(cp[C_DECEL], cs[S_ES : S_ES + N_ES]),
            cp[C_LAT],
            umax,
            cp[C_KJ],
        )
    cs[S_GUARD] = 1.0 if ug != u else 0.0
    cs[S_PREVY] = y_rad
    u = _clip(ug, umax)
    if cp[C_BELT] == 0.0:  # time full commands: the rig's own acceleration caps the guard's
        measure_full_command(cs[S_ES : S_ES + N_ES], y_rad, u, umax, cp[C_MSET], cp[C_MWIN], dt)
    # 5. observer predictions with the applied command.
    _predict(cp[C_A : C_A + 9], cp[C_B : C_B + 3], cs[S_X : S_X + 3], th, om, dist, u)
    _predict(cp[C_GA : C_GA + 9], cp[C_GB : C_GB + 3], cs[S_GX : S_GX + 3], g_th, g_om, g_d, u)
    cs[S_TH] = th
    cs[S_OM] = om
    cs[S_U] = u
    return u
