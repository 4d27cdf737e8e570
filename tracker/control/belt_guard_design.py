"""Design of the belt guard (:mod:`tracker.control.belt_guard`) on a model with ``compliance``.

Two-mass model (zero-order hold), observer gain (steady-state Kalman), backup (discrete LQI),
the Lyapunov certificate that lets the compiled prediction end early, the backup's robustness
check against hidden delay, torque and belt-frequency errors, and the packing of all of it
into the parameter vector the compiled guard reads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control
import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from tracker.control.belt_guard import (
    G_A,
    G_B,
    G_DT,
    G_HI,
    G_INVK,
    G_K,
    G_L,
    G_LO,
    G_N,
    G_ND,
    G_NP,
    G_P,
    G_PHI,
    G_PIL,
    G_PIU,
    G_PLO,
    G_UB,
    MAX_DELAY_SAMPLES,
    N_GP,
)
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel
from tracker.units import AMPLIFIER_LIMIT_V

FloatArray = NDArray[np.float64]

N_X = 5  # [θm, ωm, θl, ωl, d]
# The lowest amplifier clip the guard assumes (limits.py); the backup never asks for more.
BACKUP_LIMIT_V = 7.0
# Command delay the model may not know of (on top of its own ``delay.seconds``).
HIDDEN_DELAY_S = 0.003
# Backup LQI weights: load angle (1/rad²), velocities (s²/rad²), integral (1/(rad·s)²), volts.
Q_LOAD, Q_VEL, Q_INT, R_V = 1e2, 0.1, 1e3, 1.0
# Observer noise: velocity and torque random walks per sample, encoder (quantization) variance.
W_VEL, W_TORQUE, V_ENC = 1e-3, 1e-5, 3e-9
# The backup holds the load at least this far inside the guard line.
HOLD_MARGIN_RAD = math.radians(1.0)


@dataclass(frozen=True, slots=True)
class BeltGuardDesign:
    """The belt guard of one axis, designed on a model with ``compliance``.

    ``a`` (5, 5) and ``b`` (5,) (rad, rad/s and N·m per V) the discrete model of
    [θm, ωm, θl, ωl, d]; ``l`` (5,) the current-form observer gain; ``gain`` (5,) the backup
    u = −gain·[θm − p, ωm, θl − p, ωl, ∫(θl − p)dt] (V); ``model_delay_samples`` the
    model's command delay; ``prediction_delay_samples`` that plus the hidden bound;
    ``certificate`` (n, n) the Lyapunov matrix P of the predicted backup loop (see
    :func:`backup_loop_matrix`, n = 6 + prediction delay): once the deviation e from the hold
    equilibrium has e'Pe ≤ c, the load stays within √(c·(P⁻¹)₂₂) of the hold point and the
    backup's command within √(c·(P⁻¹)ₙₙ) of its equilibrium, so the prediction can stop.
    """

    a: FloatArray
    b: FloatArray
    l: FloatArray  # noqa: E741 - the textbook name of the observer gain
    gain: FloatArray
    model_delay_samples: int
    prediction_delay_samples: int
    dt_s: float
    gain_nm_per_v: float
    certificate: FloatArray


def two_mass_matrices(model: AxisModel, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """ZOH-discretised belt model of [θm, ωm, θl, ωl, d] driven by u (V): A (5, 5), B (5,)."""
    if not model.has("compliance"):
        raise ConfigError("the belt guard needs a model with the compliance effect")
    p = model.params
    j, frac, f_hz, zeta = (
        p["inertia.J"],
        p["inertia.motor_fraction"],
        p["compliance.frequency"],
        p["compliance.damping"],
    )
    jm, jl = j * frac, j * (1.0 - frac)
    j_eff = jm * jl / j
    k = (2.0 * math.pi * f_hz) ** 2 * j_eff
    c = 2.0 * zeta * math.sqrt(k * j_eff)
    b = p["viscous.b"]
    ac = np.array(
        [
            [0.0, 1.0, 0.0, 0.0, 0.0],
            [-k / jm, -(b + c) / jm, k / jm, c / jm, 1.0 / jm],
            [0.0, 0.0, 0.0, 1.0, 0.0],
            [k / jl, c / jl, -k / jl, -c / jl, 0.0],
            [0.0, 0.0, 0.0, 0.0, 0.0],
        ]
    )
    bc = np.array([0.0, model.gain_nm_per_v / jm, 0.0, 0.0, 0.0])
    m = np.zeros((N_X + 1, N_X + 1))
    m[:N_X, :N_X] = ac * dt_s
    m[:N_X, N_X] = bc * dt_s
    e = scipy.linalg.expm(m)
    return e[:N_X, :N_X].copy(), e[:N_X, N_X].copy()


def design_belt_guard(model: AxisModel, dt_s: float) -> BeltGuardDesign:
    """Observer (steady-state Kalman) and backup (LQI) for ``model``'s belt at sample time ``dt_s``."""
    a, b = two_mass_matrices(model, dt_s)
    c = np.array([[1.0, 0.0, 0.0, 0.0, 0.0]])
    w = np.diag([0.0, W_VEL, 0.0, W_VEL, W_TORQUE])
    p_cov = scipy.linalg.solve_discrete_are(a.T, c.T, w, np.array([[V_ENC]]))
    l_cur = (p_cov @ c.T / (c @ p_cov @ c.T + V_ENC)).reshape(-1)
    # LQI: the four mechanical states plus the integral of the load angle.
    ai = np.zeros((5, 5))
    ai[:4, :4] = a[:4, :4]
    ai[4, 2] = dt_s
    ai[4, 4] = 1.0
    bi = np.concatenate([b[:4], [0.0]]).reshape(-1, 1)
    q = np.diag([0.0, 0.1 * Q_VEL, Q_LOAD, Q_VEL, Q_INT])
    gain, _, _ = control.dlqr(ai, bi, q, np.array([[R_V]]))
    delay = int(round(model.params.get("delay.seconds", 0.0) / dt_s))
    pred = delay + int(math.ceil(HIDDEN_DELAY_S / dt_s - 1e-9))
    if pred > MAX_DELAY_SAMPLES:
        raise ConfigError(
            f"the model's command delay {model.params.get('delay.seconds', 0.0)!r} s is too long for "
            f"the belt guard (at most {(MAX_DELAY_SAMPLES * dt_s - HIDDEN_DELAY_S):g} s)"
        )
    g = np.asarray(gain, dtype=float).reshape(-1)
    phi = backup_loop_matrix(a, b, g, pred, dt_s)
    if np.max(np.abs(np.linalg.eigvals(phi))) >= 1.0:
        raise ConfigError(
            "the belt guard's backup is unstable on its own model "
            f"(belt {model.params['compliance.frequency']:g} Hz)"
        )
    cert = scipy.linalg.solve_discrete_lyapunov(phi.T, np.eye(phi.shape[0]))
    return BeltGuardDesign(a, b, l_cur, g, delay, pred, dt_s, model.gain_nm_per_v, cert)


def backup_loop_matrix(
    a: FloatArray, b: FloatArray, gain: FloatArray, delay_samples: int, dt_s: float
) -> FloatArray:
    """The predicted backup loop as one matrix Φ on e = [θm, ωm, θl, ωl (4), ∫ (1), queue (nd + 1)].

    Deviations from the hold equilibrium; queue[0] is the command acting over the next sample,
    queue[nd] the newest. One prediction step: x ← A₄x + B₄·queue[0]; u = −gain·[x, ∫];
    ∫ ← ∫ + Ts·θl; the queue shifts and takes u. Shape (6 + nd, 6 + nd).
    """
    nd = delay_samples
    n = 6 + nd
    a4, b4 = a[:4, :4], b[:4]
    step = np.zeros((n, n))
    step[:4, :4] = a4
    step[:4, 5] = b4
    step[4, 4] = 1.0
    for i in range(nd):
        step[5 + i, 6 + i] = 1.0  # the queue shifts (its newest slot is filled below)
    # The newest slot: u = −g·[x⁺, ∫] with x⁺ the stepped state and the old integral.
    u_row = -(gain[:4] @ step[:4, :]) - gain[4] * np.eye(n)[4]
    step[5 + nd, :] = u_row
    # The integral takes the stepped load angle.
    step[4, :] = np.eye(n)[4] + dt_s * step[2, :]
    return step


def backup_spectral_radius(
    design: BeltGuardDesign, plant: AxisModel, delay_samples: int, gain_scale: float = 1.0
) -> float:
    """Spectral radius of the backup's linear closed loop (observer + LQI) around ``plant``.

    ``plant`` is a belt model (its frequency may differ from the design's), the command reaches
    it ``delay_samples`` late and ``gain_scale`` times as strong. Below 1: the backup holds.
    """
    ap, bp = two_mass_matrices(plant, design.dt_s)
    ap4, bp4 = ap[:4, :4], bp[:4]
    a, b, l_c, g = design.a, design.b, design.l, design.gain
    cy = np.array([1.0, 0.0, 0.0, 0.0, 0.0])
    ilc = np.eye(N_X) - np.outer(l_c, cy)
    gx = np.concatenate([g[:4], [0.0]])
    # Controller state [x⁻ (5), ∫]: x̂ = (I − LC) x⁻ + L y, u = −gx·x̂ − g4·∫.
    cc = np.concatenate([-gx @ ilc, [-g[4]]])
    dc = float(-gx @ l_c)
    m = N_X + 1
    ac = np.zeros((m, m))
    bc = np.zeros(m)
    ac[:N_X, :N_X] = a @ ilc + np.outer(b, cc[:N_X])
    ac[:N_X, N_X] = b * cc[N_X]
    bc[:N_X] = a @ l_c + b * dc
    e_l = np.array([0.0, 0.0, 1.0, 0.0, 0.0])
    ac[N_X, :N_X] = design.dt_s * e_l @ ilc
    ac[N_X, N_X] = 1.0
    bc[N_X] = design.dt_s * float(e_l @ l_c)
    nd = delay_samples
    n = 4 + nd + m
    t = np.zeros((n, n))
    cp = np.array([1.0, 0.0, 0.0, 0.0])
    ux = gain_scale * dc * cp
    uc = gain_scale * cc
    if nd == 0:
        t[:4, :4] = ap4 + np.outer(bp4, ux)
        t[:4, 4:] = np.outer(bp4, uc)
    else:
        t[:4, :4] = ap4
        t[:4, 4 + nd - 1] = bp4
        t[4, :4] = ux
        t[4, 4 + nd :] = uc
        for i in range(1, nd):
            t[4 + i, 4 + i - 1] = 1.0
    t[4 + nd :, :4] = np.outer(bc, cp)
    t[4 + nd :, 4 + nd :] = ac
    return float(np.max(np.abs(np.linalg.eigvals(t))))


def pack_belt_guard(design: BeltGuardDesign, lo_line_rad: float, hi_line_rad: float) -> FloatArray:
    """The guard's parameters for the compiled step, shape (N_GP,).

    The load must stay within [``lo_line_rad``, ``hi_line_rad``]; the backup holds it at most
    ``HOLD_MARGIN_RAD`` inside those lines (or at their middle if they are closer).
    """
    gp = np.zeros(N_GP)
    gp[G_A : G_A + 25] = design.a.reshape(-1)
    gp[G_B : G_B + 5] = design.b
    gp[G_L : G_L + 5] = design.l
    gp[G_K : G_K + 5] = design.gain
    gp[G_ND] = design.model_delay_samples
    gp[G_NP] = design.prediction_delay_samples
    gp[G_UB] = min(BACKUP_LIMIT_V, AMPLIFIER_LIMIT_V)
    gp[G_DT] = design.dt_s
    gp[G_LO], gp[G_HI] = lo_line_rad, hi_line_rad
    hold = min(HOLD_MARGIN_RAD, 0.5 * (hi_line_rad - lo_line_rad))
    gp[G_PLO], gp[G_PHI] = lo_line_rad + hold, hi_line_rad - hold
    cert = design.certificate
    n = cert.shape[0]
    inv = np.linalg.inv(cert)
    gp[G_N], gp[G_PIL], gp[G_PIU], gp[G_INVK] = n, inv[2, 2], inv[n - 1, n - 1], 1.0 / design.gain_nm_per_v
    gp[G_P : G_P + n * n] = cert.reshape(-1)
    return gp
