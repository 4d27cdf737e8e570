"""Estimate the axis state (angle, velocity, acceleration, hidden load side) at every sample of a log.

The encoder reports the motor angle in whole counts, so differencing it gives velocity noise
of ``step/dt`` (0.19 rad/s on the seed's pan axis at 1 kHz). We smooth instead: a
forward–backward Kalman smoother (Rauch–Tung–Striebel) on a constant-acceleration model
driven by white jerk, with the quantization noise ``step²/12`` as measurement noise. The jerk
intensity is chosen by maximum likelihood of the forward filter's innovations over a grid of
bandwidths, so steps in the command (jumps in acceleration) and slow ramps are both followed.

Two-mass models (``backlash``, ``compliance``) hide the load side from the encoder. We estimate
it with a model-based (Luenberger) observer run along the data: the full two-mass model is
simulated with the measured command and its motor side is pulled toward the encoder at every
sample; the load side follows through the model's belt and dead band. The motor side keeps the
smoother's estimate (so rigid and two-mass models start their predictions from the same motor
state); the load side comes from the observer. Through a backlash gap the load is only weakly
observable (it coasts while the motor is stuck), which limits what k-step prediction can do there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.plant.effects.saturation import drive_rail_v
from tracker.plant.model import AxisModel
from tracker.plant.simulate import STATE_SIZE, advance, pack_params
from tracker.workbench.measurements.data import Measurement

FloatArray = NDArray[np.float64]

# Smoother bandwidths tried (Hz); the likeliest wins. Spans slow ramps to belt resonances.
BANDWIDTHS_HZ = (3.0, 6.0, 12.0, 25.0, 50.0, 100.0)
# The encoder must read the same count this long to call the axis held (at rest).
HOLD_MIN_S = 0.05
# Longest command-to-acceleration lag the smoother looks for (amplifier and bus delays).
MAX_COMMAND_LAG_S = 0.04
# Samples of a hold given to the neighbouring motion's smoother (where the take-off may be).
ANCHOR_MARGIN = 15
# Samples used to choose the smoother bandwidth by likelihood.
LIKELIHOOD_SAMPLES = 12000
# Bandwidth of the model-based observer's motor-side correction (two-mass models).
OBSERVER_BANDWIDTH_HZ = 80.0


@dataclass(frozen=True, slots=True)
class StateEstimate:
    """Estimated state at every sample; every array has shape (n,).

    ``theta_rad``/``omega_rad_s``/``alpha_rad_s2`` are the motor (encoder) side.
    ``load_theta_rad``/``load_omega_rad_s`` are the load side: equal to the motor side for a
    rigid axis, estimated by the observer for two-mass models. ``noise_rad`` is the measurement
    noise standard deviation used and ``bandwidth_hz`` the smoother bandwidth chosen.
    """

    theta_rad: FloatArray
    omega_rad_s: FloatArray
    alpha_rad_s2: FloatArray
    load_theta_rad: FloatArray
    load_omega_rad_s: FloatArray
    noise_rad: float
    bandwidth_hz: float
    dt_s: float

    def initial_states(self, starts: NDArray[np.int64]) -> FloatArray:
        """Simulator states ``[θm, ωm, θl, ωl]`` at samples ``starts``. Returns shape (m, 4).

        The simulator's semi-implicit Euler step is θ_{k+1} = θ_k + h·ω_{k+1}: its velocity
        state at sample k is the one that carried θ from k−1 to k, i.e. ω(t_k − h/2). Starting
        a prediction from the smooth ω(t_k) instead biases every k-step prediction by
        (h/2)·α·T — which a fit would absorb as a J too large by h/T (6 % at 20 ms).
        """
        s = np.asarray(starts, dtype=np.int64)
        x0 = np.empty((s.size, STATE_SIZE))
        x0[:, 0] = self.theta_rad[s]
        prev = np.maximum(s - 1, 0)
        # v_k = ω(t_k) − ½h·α over the *previous* interval (it differs after a command step).
        x0[:, 1] = self.omega_rad_s[s] - 0.5 * self.dt_s * self.alpha_rad_s2[prev]
        x0[:, 2] = self.load_theta_rad[s]
        x0[:, 3] = self.load_omega_rad_s[s] - 0.5 * self.dt_s * self.alpha_rad_s2[prev]
        return x0


def encoder_step_rad(theta_rad: FloatArray) -> float:
    """The encoder count seen in ``theta_rad`` (the smallest step between samples), or 0.

    Returns 0.0 when the steps are not whole multiples of one count (unquantized data).
    """
    d = np.abs(np.diff(np.asarray(theta_rad, dtype=float)))
    scale = float(np.max(np.abs(theta_rad))) if theta_rad.size else 0.0
    d = d[d > 1e-12 * max(scale, 1e-30)]
    if d.size < 10:
        return 0.0
    q = float(np.min(d))
    ratio = d / q
    if np.mean(np.abs(ratio - np.round(ratio)) < 0.02) > 0.98:
        return q
    return 0.0


def measurement_noise_rad(theta_rad: FloatArray) -> float:
    """Standard deviation of the angle's measurement noise (quantization or white), rad.

    Quantized data: ``step/√12``. Otherwise the third difference of a smooth signal is mostly
    noise, with variance 20σ²; a robust (median-based) spread keeps fast moves out of it.
    """
    q = encoder_step_rad(theta_rad)
    d3 = np.diff(np.asarray(theta_rad, dtype=float), 3)
    sigma_white = 1.4826 * float(np.median(np.abs(d3 - np.median(d3)))) / math.sqrt(20.0)
    sigma = max(q / math.sqrt(12.0), sigma_white)
    if sigma <= 0.0:
        scale = float(np.max(np.abs(theta_rad))) or 1.0
        sigma = 1e-9 * scale
    return sigma


# No known acceleration jumps. Compiled functions take every argument explicitly: numba keys
# its on-disk cache by argument types, and an omitted default recompiles in every process.
_NO_JUMP = np.zeros(0)

# The filter's covariances converge long before this many samples (the model is time
# invariant); after it the gains are held, which makes every pass a few multiply-adds.
CONVERGED_AFTER = 800


@njit(cache=True)
def _covariances(
    n: int, dt: float, r: float, q: float, at_rest: bool
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Predicted/filtered covariances for the first min(n, CONVERGED_AFTER) steps, and F.

    ``at_rest``: the first sample is known to be at rest (ω = 0 exactly; α unknown).
    """
    m = min(n, CONVERGED_AFTER)
    F = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    dt2, dt3, dt4, dt5 = dt * dt, dt**3, dt**4, dt**5
    Q = q * np.array(
        [[dt5 / 20.0, dt4 / 8.0, dt3 / 6.0], [dt4 / 8.0, dt3 / 3.0, dt2 / 2.0], [dt3 / 6.0, dt2 / 2.0, dt]]
    )
    Pp = np.zeros((m, 3, 3))
    Pf = np.zeros((m, 3, 3))
    p_omega = 1e-8 * r / dt2 if at_rest else 1e6 * r / dt2
    P = np.diag(np.array([r, p_omega, 1e6 * r / (dt2 * dt2)]))
    for k in range(m):
        if k > 0:
            P = F @ P @ F.T + Q
        Pp[k] = P
        s = P[0, 0] + r
        K = P[:, 0] / s
        P = P - np.outer(K, P[0, :])
        Pf[k] = P
    return Pp, Pf, F


@njit(cache=True)
def _forward(
    y: FloatArray, r: float, Pp: FloatArray, F: FloatArray, jump: FloatArray
) -> tuple[FloatArray, FloatArray, float]:
    """Kalman filter: predicted and filtered states (n, 3) and the innovation log-likelihood.

    ``jump[k]`` is a known change of acceleration from sample k−1 to k (the command's step
    times K/J), or an empty array for none.
    """
    n = y.shape[0]
    m = Pp.shape[0]
    dt = F[0, 1]
    xp = np.empty((n, 3))
    xf = np.empty((n, 3))
    a0, a1, a2 = y[0], 0.0, 0.0
    has_jump = jump.shape[0] == n
    loglik = 0.0
    log2pi = math.log(2.0 * math.pi)
    for k in range(n):
        if k > 0:
            a0 = a0 + dt * a1 + 0.5 * dt * dt * a2
            a1 = a1 + dt * a2
            if has_jump:
                a2 = a2 + jump[k]
        xp[k, 0], xp[k, 1], xp[k, 2] = a0, a1, a2
        j = k if k < m else m - 1
        s = Pp[j, 0, 0] + r
        innov = y[k] - a0
        if k > 2:
            loglik += -0.5 * (log2pi + math.log(s) + innov * innov / s)
        g = innov / s
        a0 += Pp[j, 0, 0] * g
        a1 += Pp[j, 1, 0] * g
        a2 += Pp[j, 2, 0] * g
        xf[k, 0], xf[k, 1], xf[k, 2] = a0, a1, a2
    return xp, xf, loglik


@njit(cache=True)
def _rts_ca(
    y: FloatArray, dt: float, r: float, q: float, at_rest: bool, jump: FloatArray
) -> tuple[FloatArray, float]:
    """RTS smoother, constant acceleration, white jerk of intensity q (plus known acceleration
    jumps). Returns (n, 3), loglik."""
    n = y.shape[0]
    Pp, Pf, F = _covariances(n, dt, r, q, at_rest)
    m = Pp.shape[0]
    xp, xf, loglik = _forward(y, r, Pp, F, jump)
    xs = np.empty((n, 3))
    xs[n - 1] = xf[n - 1]
    C_ss = Pf[m - 1] @ F.T @ np.linalg.inv(Pp[m - 1])
    for k in range(n - 2, -1, -1):
        if k + 1 < m:
            C = Pf[k] @ F.T @ np.linalg.inv(Pp[k + 1])
        else:
            C = C_ss
        xs[k] = xf[k] + C @ (xs[k + 1] - xp[k + 1])
    return xs, loglik


def _filter_loglik(y: FloatArray, dt: float, r: float, q: float, jump: FloatArray = _NO_JUMP) -> float:
    """Forward Kalman filter log-likelihood only (bandwidth selection)."""
    Pp, _, F = _covariances(y.shape[0], dt, r, q, False)
    return float(_forward(y, r, Pp, F, jump)[2])


def jerk_intensity(noise_rad: float, bandwidth_hz: float) -> float:
    """White-jerk intensity q giving a smoother of roughly ``bandwidth_hz`` (q = r·ω⁶)."""
    w = 2.0 * math.pi * bandwidth_hz
    return noise_rad**2 * w**6


def _pick_bandwidth(y: FloatArray, dt_s: float, jump: FloatArray) -> float:
    sub = slice(0, min(y.size, LIKELIHOOD_SAMPLES))
    nyq = 0.5 / dt_s
    cands = [b for b in BANDWIDTHS_HZ if b < 0.4 * nyq] or [0.2 * nyq]
    j = jump[sub] if jump.size else jump
    lls = [_filter_loglik(np.ascontiguousarray(y[sub]), dt_s, 1.0, jerk_intensity(1.0, b), j) for b in cands]
    return float(cands[int(np.argmax(lls))])


def command_acceleration(xs: FloatArray, u_v: FloatArray, dt_s: float) -> tuple[float, int]:
    """How the acceleration follows the command: (gain K/J in units of ``xs`` per volt, lag in samples).

    Least squares of α on [u(t − d), ω, sign ω, 1] over moving samples for lags d up to
    :data:`MAX_COMMAND_LAG_S`; returns (0, 0) when the command explains little (R² < 0.3).
    """
    om, al = xs[:, 1], xs[:, 2]
    w95 = float(np.percentile(np.abs(om), 95)) or 1.0
    mov = np.abs(om) > 0.03 * w95
    if mov.sum() < 50:
        return 0.0, 0
    best = (0.0, 0, 0.3)
    tss = float(np.sum((al[mov] - al[mov].mean()) ** 2)) or 1.0
    for d in range(0, int(round(MAX_COMMAND_LAG_S / dt_s)) + 1, max(1, int(round(0.002 / dt_s)))):
        ud = np.concatenate([np.full(d, u_v[0]), u_v[: u_v.size - d]]) if d else u_v
        a = np.column_stack([ud[mov], om[mov], np.sign(om[mov]), np.ones(int(mov.sum()))])
        coef, res, *_ = np.linalg.lstsq(a, al[mov], rcond=None)
        r2 = 1.0 - (float(res[0]) if res.size else tss) / tss
        if r2 > best[2] and coef[0] > 0:
            best = (float(coef[0]), d, r2)
    return best[0], best[1]


def smooth_kinematics(
    theta_rad: FloatArray, dt_s: float, bandwidth_hz: float | None = None, u_v: FloatArray | None = None
) -> tuple[FloatArray, float, float]:
    """RTS-smoothed ``[θ, ω, α]`` of a sampled angle. Returns (shape (n, 3), noise_rad, bandwidth_hz).

    ``bandwidth_hz=None`` picks the bandwidth of :data:`BANDWIDTHS_HZ` with the highest
    innovation likelihood (evaluated on the first LIKELIHOOD_SAMPLES samples for speed).
    With the command ``u_v`` the smoother also knows that the acceleration jumps when the
    command steps (by K/J, estimated from a first pass, at the lag the data show): a pure
    kinematic smoother spreads every such step over its bandwidth and misplaces the velocity
    at starts and reversals.
    """
    y_raw = np.ascontiguousarray(theta_rad, dtype=float)
    sigma = measurement_noise_rad(y_raw)
    # Work in units of the noise (r = 1): keeps the covariances well scaled for any unit.
    offset = float(y_raw[0])
    y = (y_raw - offset) / sigma
    jump = _NO_JUMP
    bw = _pick_bandwidth(y, dt_s, jump) if bandwidth_hz is None else bandwidth_hz
    xs, _ = _rts_ca(y, dt_s, 1.0, jerk_intensity(1.0, bw), False, _NO_JUMP)
    if u_v is not None:
        u = np.asarray(u_v, dtype=float)
        gain, lag = command_acceleration(xs, u, dt_s)
        if gain > 0.0:
            ud = np.concatenate([np.full(lag, u[0]), u[: u.size - lag]]) if lag else u
            jump = np.ascontiguousarray(np.concatenate([[0.0], gain * np.diff(ud)]))
            bw = _pick_bandwidth(y, dt_s, jump) if bandwidth_hz is None else bandwidth_hz
            xs, _ = _rts_ca(y, dt_s, 1.0, jerk_intensity(1.0, bw), False, jump)
    q = jerk_intensity(1.0, bw)
    if encoder_step_rad(y_raw) > 0.0 and jump.size == 0:
        _anchor_at_holds(y, xs, dt_s, q, hold_runs(y_raw, max(3, int(round(HOLD_MIN_S / dt_s)))))
    xs *= sigma
    xs[:, 0] += offset
    return xs, sigma, bw


def hold_runs(theta_rad: FloatArray, min_samples: int) -> list[tuple[int, int]]:
    """Runs ``[start, stop)`` where the encoder reads exactly the same count for at least
    ``min_samples`` samples: the axis is held (at rest), not creeping."""
    y = np.asarray(theta_rad)
    change = np.flatnonzero(np.diff(y) != 0.0) + 1
    edges = np.concatenate([[0], change, [y.size]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b - a >= min_samples]


def _anchor_at_holds(
    y: FloatArray, xs: FloatArray, dt: float, q: float, holds: list[tuple[int, int]]
) -> None:
    """Make the smoothed states (in place, noise units) respect holds: at rest inside them, and
    each motion between holds smoothed from rest (forward) and to rest (time-reversed), blended.

    A smoother that does not know the axis starts from rest blurs every start: its velocity
    leaks ahead into the hold and lags behind the take-off (0.04 rad/s on the pan axis, which
    made k-step errors 20× larger at starts than elsewhere with a perfect model).
    """
    n = y.size
    for a, b in holds:
        xs[a:b, 0] = y[a]
        xs[a:b, 1:] = 0.0
    # Each motion segment takes in a margin of the holds around it: the take-off happens
    # somewhere before the count first changes, and the smoother must be free to put it there.
    margin = [min(ANCHOR_MARGIN, (b - a) // 2) for a, b in holds]
    bounds: list[tuple[int | None, int | None]] = []
    if holds and holds[0][0] > 0:
        bounds.append((None, holds[0][0] + margin[0]))
    bounds += [(holds[i][1] - margin[i], holds[i + 1][0] + margin[i + 1]) for i in range(len(holds) - 1)]
    if holds and holds[-1][1] < n:
        bounds.append((holds[-1][1] - margin[-1], None))
    for start, stop in bounds:
        lo = 0 if start is None else start
        hi = n - 1 if stop is None else stop
        if hi - lo < 3:
            continue
        seg = np.ascontiguousarray(y[lo : hi + 1])
        blend = np.linspace(0.0, 1.0, seg.size)[:, None]
        fwd = _rts_ca(seg, dt, 1.0, q, True, _NO_JUMP)[0] if start is not None else xs[lo : hi + 1].copy()
        if stop is not None:
            bwd = _rts_ca(np.ascontiguousarray(seg[::-1]), dt, 1.0, q, True, _NO_JUMP)[0][::-1].copy()
            bwd[:, 1] *= -1.0  # time reversal flips velocity, not position or acceleration
        else:
            bwd = xs[lo : hi + 1].copy()
        if start is None:
            blend[:] = 1.0
        elif stop is None:
            blend[:] = 0.0
        xs[lo : hi + 1] = (1.0 - blend) * fwd + blend * bwd


@njit(cache=True)
def _model_observer(
    P: FloatArray, u: FloatArray, y: FloatArray, dt: float, x0: FloatArray, l_pos: float, l_vel: float
) -> FloatArray:
    """Luenberger observer on the full model: predict with the simulator, correct the motor
    side toward the encoder. Returns the state at every sample, shape (n, 4)."""
    n = y.shape[0]
    out = np.empty((n, STATE_SIZE))
    x = x0.copy()
    for k in range(n):
        innov = y[k] - x[0]
        x[0] += l_pos * innov
        x[1] += l_vel * innov
        out[k] = x
        if k < n - 1:
            advance(x, P, u, k, dt, 0.0)
    return out


def observe_states(
    model: AxisModel, meas: Measurement, bandwidth_hz: float = OBSERVER_BANDWIDTH_HZ
) -> FloatArray:
    """Run the model-based observer along ``meas``: states ``[θm, ωm, θl, ωl]``, shape (n, 4).

    The motor-side error dynamics get both poles at exp(−2π·bandwidth·dt): gains
    l_pos = 1 − p², l_vel = (1 − p)²/dt. The load side is carried by the model (spring, dead
    band, gravity), which is what makes it observable through the motor: during a backlash
    traversal the model knows the light motor crosses the gap while the load coasts.
    """
    dt = meas.dt_s
    P = pack_params(model, dt, quantize=False, rail_v=drive_rail_v(meas.u_v))
    p = math.exp(-2.0 * math.pi * bandwidth_hz * dt)
    y = np.ascontiguousarray(meas.theta_rad, dtype=float)
    x0 = np.array([y[0], 0.0, y[0], 0.0])
    return _model_observer(
        P, np.ascontiguousarray(meas.u_v, dtype=float), y, dt, x0, 1.0 - p * p, (1.0 - p) ** 2 / dt
    )


def estimate_states(
    meas: Measurement, model: AxisModel | None = None, bandwidth_hz: float | None = None
) -> StateEstimate:
    """Estimate the state at every sample of ``meas``.

    Parameters
    ----------
    meas : the measured log (encoder angle, rad, possibly quantized).
    model : when it has ``backlash`` or ``compliance``, the load side is estimated by the
        model-based observer; otherwise (or None) the load side equals the motor side.
    bandwidth_hz : smoother bandwidth; None chooses it by maximum likelihood.

    Returns
    -------
    StateEstimate with arrays of shape (n,).
    """
    dt = meas.dt_s
    xs, sigma, bw = smooth_kinematics(meas.theta_rad, dt, bandwidth_hz, meas.u_v)
    th, om, al = xs[:, 0].copy(), xs[:, 1].copy(), xs[:, 2].copy()
    est = StateEstimate(th, om, al, th, om, sigma, bw, dt)
    return est if model is None else with_load_observer(est, model, meas)


def with_load_observer(est: StateEstimate, model: AxisModel, meas: Measurement) -> StateEstimate:
    """``est`` with its load side re-estimated for ``model`` by :func:`observe_states`.

    Rigid models get the motor side back. Cheap (one compiled pass); the fitter calls it at
    every evaluation because the load estimate depends on the two-mass parameters.
    """
    if not (model.has("backlash") or model.has("compliance")):
        th_l, om_l = est.theta_rad, est.omega_rad_s
    else:
        xs = observe_states(model, meas)
        # Back from the simulator's half-step velocity convention to the smooth one.
        th_l, om_l = xs[:, 2].copy(), xs[:, 3] + 0.5 * meas.dt_s * est.alpha_rad_s2
    return StateEstimate(
        est.theta_rad,
        est.omega_rad_s,
        est.alpha_rad_s2,
        th_l,
        om_l,
        est.noise_rad,
        est.bandwidth_hz,
        meas.dt_s,
    )


__all__ = [
    "StateEstimate",
    "encoder_step_rad",
    "estimate_states",
    "hold_runs",
    "measurement_noise_rad",
    "observe_states",
    "smooth_kinematics",
    "with_load_observer",
]
