"""The compiled closed loop: controller + plant twin in one numba loop (1 h of 1 kHz in seconds).

:func:`run_chunk` advances one axis by n samples: each sample reads the encoder, runs
:func:`tracker.control.loop.controller_step`, and advances the plant with
:func:`tracker.plant.simulate.advance`. It carries every state across calls, so the engine can
run 10 ms chunks in real time and a batch can run an hour in one call. :func:`simulate_closed_loop`
is the convenient whole-run form used by the command line, the tests and the workbench.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.control.envelope import BrakingEnvelope
from tracker.control.gains import ControllerGains
from tracker.control.limits import SoftLimits
from tracker.control.loop import S_INIT, S_OM, S_REF, controller_step, new_state, pack_controller
from tracker.control.trajectory import TrajectoryLimits
from tracker.errors import DataError
from tracker.plant.model import AxisModel
from tracker.plant.simulate import I_DELAY, advance, encoder_rad, initial_state, pack_params

FloatArray = NDArray[np.float64]

# Columns of the per-sample record written by run_chunk.
R_Y, R_U, R_LOAD, R_REF, R_OMEGA_HAT, R_LOAD_OMEGA = 0, 1, 2, 3, 4, 5
N_REC = 6
# For runs without soft limits (design studies): far beyond any angle the twin reaches.
UNLIMITED = SoftLimits(-1e6, 1e6)


def history_length(plant_p: FloatArray, dt_s: float) -> int:
    """Samples of command history the plant's delay needs (at least 2)."""
    return int(math.ceil(plant_p[I_DELAY] / dt_s)) + 2


# nogil: the engine's thread runs a chunk while the service's thread keeps serving (arrays only,
# each engine's own). controller_step (per sample, ~2 µs) keeps the GIL: giving it up and
# taking it back every sample would cost more than it frees.
@njit(cache=True, nogil=True)
def run_chunk(
    plant_p: FloatArray,
    cp: FloatArray,
    cs: FloatArray,
    x: FloatArray,
    u_hist: FloatArray,
    targets: FloatArray,
    dist_nm: FloatArray,
    enabled: bool,
    hard_limit_rad: float,
    rec: FloatArray,
) -> int:
    """Run ``targets.shape[0]`` samples of controller + plant; states update in place.

    ``u_hist`` (shape (h,)) holds the last h commands (oldest first) for the plant's delay and
    is updated. ``dist_nm`` is an external load torque per sample (shape (n,) or (0,)).
    ``rec`` (shape (n, N_REC)) receives encoder, command, load angle, reference, observed
    velocity and load velocity per sample. With ``enabled`` False the amplifier gets 0 V.
    Returns the number of samples run: fewer than n when the load passed ``hard_limit_rad``.
    """
    n = targets.shape[0]
    h = u_hist.shape[0]
    buf = np.empty(h + n)
    buf[:h] = u_hist
    dt = cp[1]
    has_dist = dist_nm.shape[0] == n
    done = n
    for k in range(n):
        y = encoder_rad(x, plant_p)
        if enabled:
            u = controller_step(cp, cs, y, targets[k])
        else:
            u = 0.0
            cs[S_INIT] = 0.0  # re-initialise the controller on re-enable
        buf[h + k] = u
        rec[k, 0] = y
        rec[k, 1] = u
        rec[k, 2] = x[2]
        rec[k, 3] = cs[S_REF]
        rec[k, 4] = cs[S_OM]
        rec[k, 5] = x[3]
        advance(x, plant_p, buf, h + k, dt, dist_nm[k] if has_dist else 0.0)
        if abs(x[2]) > hard_limit_rad:
            done = k + 1
            break
    u_hist[:] = buf[done : done + h]
    return int(done)


@dataclass(frozen=True, slots=True)
class ClosedLoopResult:
    """A closed-loop run of one axis; arrays have shape (n,), sample k at ``t_s[k]``.

    ``theta_rad`` is the encoder, ``load_theta_rad`` where the camera points, ``reference_rad``
    the shaped reference, ``omega_hat_rad_s`` the observer's velocity.
    """

    t_s: FloatArray
    target_rad: FloatArray
    u_v: FloatArray
    theta_rad: FloatArray
    load_theta_rad: FloatArray
    reference_rad: FloatArray
    omega_hat_rad_s: FloatArray
    load_omega_rad_s: FloatArray


def simulate_closed_loop(
    plant: AxisModel,
    design_model: AxisModel,
    gains: ControllerGains,
    targets_rad: FloatArray,
    dt_s: float = 1e-3,
    limits: SoftLimits | None = None,
    shaping: TrajectoryLimits | None = None,
    theta0_rad: float = 0.0,
    disturbance_nm: FloatArray | None = None,
    velocity_source: float = 0.0,
    hard_limit_rad: float = math.inf,
    envelope: BrakingEnvelope | None = None,
) -> ClosedLoopResult:
    """Close the loop of ``gains`` (designed on ``design_model``) around the twin ``plant``.

    ``targets_rad`` has shape (n,), one target per sample. ``plant`` may hold effects the
    design model lacks (that is the point of a twin). ``envelope``: the rig's rated braking for
    the soft-limit guard (None: the design model's, see :func:`tracker.control.loop.pack_controller`).
    """
    tgt = np.ascontiguousarray(targets_rad, dtype=float)
    if tgt.ndim != 1 or tgt.size == 0:
        raise DataError(f"targets must be a non-empty 1-D array, got shape {tgt.shape}")
    lim = limits if limits is not None else UNLIMITED
    cp = pack_controller(design_model, gains, dt_s, lim, shaping, velocity_source, envelope)
    pp = pack_params(plant, dt_s, quantize=True)
    x = initial_state(theta0_rad)
    cs = new_state()
    u_hist = np.zeros(history_length(pp, dt_s))
    dist = np.zeros(0) if disturbance_nm is None else np.ascontiguousarray(disturbance_nm, dtype=float)
    rec = np.empty((tgt.size, N_REC))
    n = run_chunk(pp, cp, cs, x, u_hist, tgt, dist, True, hard_limit_rad, rec)
    rec = rec[:n]
    return ClosedLoopResult(
        np.arange(n, dtype=np.float64) * dt_s,
        tgt[:n],
        rec[:, R_U].copy(),
        rec[:, R_Y].copy(),
        rec[:, R_LOAD].copy(),
        rec[:, R_REF].copy(),
        rec[:, R_OMEGA_HAT].copy(),
        rec[:, R_LOAD_OMEGA].copy(),
    )
