"""What a right model's residual looks like on this run: a parametric bootstrap of the k-step error.

k-step residuals from smoothed states are correlated over the horizon by construction, and their
size is set by the sensor (encoder step, noise) as much as by the model. So the residual of a
model is judged against replicas made by the model itself: the fitted model is driven along the
measured run (the log's command, plus a soft tracking loop that keeps the replica on the measured
trajectory — an integrating axis driven open loop drifts away, and the regimes and positions must
stay those of the log), its angle is read through an encoder with the step and noise found in the
log, and the same pipeline (state smoother, refit, k-step prediction) runs on each replica. What
the replicas' residuals do — their RMS, their autocorrelation, their error per regime — is what a
right model produces on this excitation with this sensor; its spread is the band.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.plant.effects.saturation import drive_rail_v
from tracker.plant.model import AxisModel
from tracker.plant.simulate import advance, pack_params
from tracker.workbench.compare.regimes import REGIME_NAMES, regime_masks
from tracker.workbench.compare.residuals import autocorrelation
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.states import (
    StateEstimate,
    encoder_step_rad,
    estimate_states,
    with_load_observer,
)

FloatArray = NDArray[np.float64]

DEFAULT_REPLICAS = 5
# Bandwidth of the tracking loop that keeps a replica on the measured trajectory: well below the
# horizon's 1/T (it must not hide the model's own dynamics inside a window), above the slow drift.
TRACKING_BANDWIDTH_HZ = 2.0
# Largest amplitude factor by which a disturbance's calibration through the pipeline may scale it.
CALIBRATION_CAP = 2.0


@dataclass(frozen=True, slots=True)
class SensorNoise:
    """The sensor as the log shows it: encoder step (0 if unquantized) and white noise, rad.

    ``floor_rad`` is the RMS of one reading's error: √(step²/12 + white²).
    """

    encoder_step_rad: float
    white_noise_rad: float

    @property
    def floor_rad(self) -> float:
        return math.sqrt(self.encoder_step_rad**2 / 12.0 + self.white_noise_rad**2)

    @classmethod
    def from_log(cls, theta_rad: FloatArray) -> SensorNoise:
        """Step from the data's distinct increments; white noise is what the reading's spread
        shows beyond step²/12 (noise added before the encoder).

        The spread comes from third differences (variance 20·σ² for a white reading error σ;
        the motion's own third difference is tiny at these rates), as a *trimmed mean square*:
        on quantized data the third differences are whole counts, so a median-based spread
        moves in steps of a count (it read 0.0018 rad for a true 0.0014 on one log, 0.0010 for
        0.0024 on another); the mean square is continuous in σ. The trim (beyond 6 robust
        spreads, at least 6 counts) drops fast moves and command steps.
        """
        th = np.asarray(theta_rad, dtype=float)
        q = encoder_step_rad(th)
        d3 = np.diff(th, 3)
        if d3.size < 10:
            return cls(q, 0.0)
        d3 = d3 - float(np.median(d3))
        spread = 1.4826 * float(np.median(np.abs(d3)))
        cut = 6.0 * max(spread, q)
        kept = d3[np.abs(d3) <= cut] if cut > 0 else d3
        total2 = float(np.mean(kept**2)) / 20.0 if kept.size else 0.0
        white = math.sqrt(max(total2 - q**2 / 12.0, 0.0))
        return cls(q, white)


@dataclass(frozen=True, slots=True)
class ResidualFloor:
    """The k-step residual of a right model on this run, from ``replicas`` simulated replicas.

    ``rms_rad`` shape (R,): each replica's residual RMS. ``autocorr`` shape (R, M+1): each
    replica's residual autocorrelation at lags 0..M. ``regime_rms_rad`` maps a regime to shape
    (R,) (the measured run's regime masks). ``sensor`` is the noise the replicas were read with.
    """

    sensor: SensorNoise
    rms_rad: FloatArray
    autocorr: FloatArray
    regime_rms_rad: dict[str, FloatArray]
    refitted: bool
    disturbance_rms_nm: float = 0.0

    @property
    def replicas(self) -> int:
        return int(self.rms_rad.size)


def _smoothed_power(x: FloatArray, bins: int = 32) -> FloatArray:
    p = np.abs(np.fft.rfft(x)) ** 2
    kernel = np.ones(bins) / bins
    return np.asarray(np.convolve(p, kernel, mode="same"), dtype=np.float64)


def _catalogue_columns(est: StateEstimate) -> FloatArray:
    """Torques a catalogue torque effect could add, shape (n, 7): offset, Coulomb and viscous
    per direction, sin θ and cos θ (gravity)."""
    th, w = est.theta_rad, est.omega_rad_s
    neg = (w < 0).astype(float)
    return np.column_stack([np.ones(th.size), np.sign(w), w, neg, w * neg, np.sin(th), np.cos(th)])


def _window_response(k: int, dt_s: float, inertia: float) -> FloatArray:
    """How a torque at t − m moves the k-step prediction of θ(t): h[m] = (m − ½)·dt²/J, m = 0..k
    (h[0] = 0), rad per N·m — the double integral over the window of a torque error."""
    m = np.arange(k + 1, dtype=float)
    h = (m - 0.5) * dt_s * dt_s / inertia
    h[0] = 0.0
    return h


def _unexplained_k_step(resid_rad: FloatArray, est: StateEstimate, h: FloatArray, k: int) -> FloatArray:
    """The k-step residual less what a catalogue torque error would make of it, shape (n,)
    (zero before sample k): least squares on the columns passed through the window response."""
    n = resid_rad.size
    cols = _catalogue_columns(est)
    resp = np.column_stack([np.convolve(cols[:, j], h)[:n] for j in range(cols.shape[1])])
    coef, *_ = np.linalg.lstsq(resp[k:], resid_rad[k:], rcond=None)
    out = np.zeros(n)
    out[k:] = resid_rad[k:] - resp[k:] @ coef
    return out


def disturbance_amplitude(
    meas: Measurement, model: AxisModel, est: StateEstimate, horizon_s: float, sensor: SensorNoise
) -> FloatArray:
    """Fourier amplitude (rfft bins of length n) of the run's load disturbance, N·m.

    Read where it dominates the sensor: in the k-step residual (a disturbance d moves each
    prediction by h ∗ d, :func:`_window_response`), after what a catalogue torque error could
    explain is removed (so a missing offset, friction or gravity is not taken for disturbance).
    The same is done on a replica made by the model without disturbance (what the sensor
    alone leaves); the power beyond it, divided by |H(f)|², is the disturbance's, up to 0.7/T
    (above, H has its zeros). In the torque domain the sensor's share (the smoothed α of a
    quantized angle) is several times a typical disturbance, and the difference was mostly
    noise (a true 0.002 N·m read as 0.0003 on one practice log, 0.0031 on another).
    """
    from tracker.workbench.compare.compare import predict_k_step

    dt = meas.dt_s
    k = max(1, int(round(horizon_s / dt)))
    J = float(model.params.get("inertia.J", 1.0))
    h = _window_response(k, dt, J)
    resid = meas.theta_rad - predict_k_step(meas, model, est, k)
    left = _unexplained_k_step(resid, est, h, k)
    clean = replay_run(meas, model, est, sensor, np.random.default_rng(12345))
    est0 = with_load_observer(estimate_states(clean, model), model, clean)
    left0 = _unexplained_k_step(clean.theta_rad - predict_k_step(clean, model, est0, k), est0, h, k)
    p_meas, p_noise = _smoothed_power(left), _smoothed_power(left0)
    freq = np.fft.rfftfreq(meas.n, dt)
    gain2 = np.abs(np.fft.rfft(h, meas.n)) ** 2
    use = (freq > 0) & (freq < 0.7 / (k * dt)) & (gain2 > 0)
    excess = np.maximum(p_meas - p_noise, 0.0)
    amp = np.zeros(freq.size)
    amp[use] = np.sqrt(excess[use] / gain2[use])
    if not np.any(amp > 0):
        return amp
    # Calibrate through the pipeline: the smoothed states at a window's start already lean toward
    # what the disturbance does inside it, so its k-step effect is less than h ∗ d. A replica
    # with a draw of ``amp`` (the same sensor draws as the clean one) shows how much less; the
    # amplitude is scaled so the replica's excess power matches the measured run's.
    dist = disturbance_draw(amp, meas.n, np.random.default_rng(54321))
    rep = replay_run(meas, model, est, sensor, np.random.default_rng(12345), dist)
    est_d = with_load_observer(estimate_states(rep, model), model, rep)
    left_d = _unexplained_k_step(rep.theta_rad - predict_k_step(rep, model, est_d, k), est_d, h, k)
    got = float(np.sum(np.maximum(_smoothed_power(left_d) - p_noise, 0.0)[use]))
    want = float(np.sum(excess[use]))
    # The smoothed states only ever take away from the disturbance's effect (factor ≥ 1); a
    # disturbance far below the sensor's floor cannot be calibrated (``got`` is then noise), so
    # the factor is capped where the lean is ~1.2–1.4 on the logs measured.
    amp *= min(max(math.sqrt(want / got), 1.0), CALIBRATION_CAP) if got > 0 else CALIBRATION_CAP
    return np.asarray(amp, dtype=np.float64)


def disturbance_draw(amplitude: FloatArray, n: int, rng: np.random.Generator) -> FloatArray:
    """A disturbance with the Fourier ``amplitude`` and random phases, shape (n,)."""
    phases = np.exp(2j * np.pi * rng.random(amplitude.size))
    return np.asarray(np.fft.irfft(amplitude * phases, n), dtype=np.float64)


def disturbance_rms_nm(amplitude: FloatArray, n: int) -> float:
    """RMS of a disturbance drawn from ``amplitude`` (Parseval on the rfft), N·m."""
    a2 = amplitude**2
    total = a2[0] + 2.0 * np.sum(a2[1:]) - (a2[-1] if n % 2 == 0 else 0.0)
    return float(math.sqrt(max(total, 0.0)) / n)


@njit(cache=True)
def _replay(
    P: FloatArray,
    u_meas: FloatArray,
    theta_ref: FloatArray,
    omega_ref: FloatArray,
    dist: FloatArray,
    dt: float,
    x0: FloatArray,
    kp: float,
    kd: float,
) -> tuple[FloatArray, FloatArray]:
    """Drive the model with the logged command plus a PD pull toward the measured trajectory.

    Returns (u, θ) of shape (n,): the command actually applied (what the replica logs) and the
    motor angle at the samples, unquantized.
    """
    n = u_meas.shape[0]
    u = np.empty(n)
    th = np.empty(n)
    x = x0.copy()
    for i in range(n):
        th[i] = x[0]
        u[i] = u_meas[i] + kp * (theta_ref[i] - x[0]) + kd * (omega_ref[i] - x[1])
        advance(x, P, u, i, dt, dist[i])
    return u, th


def replay_run(
    meas: Measurement,
    model: AxisModel,
    est: StateEstimate,
    sensor: SensorNoise,
    rng: np.random.Generator,
    disturbance_nm: FloatArray | None = None,
) -> Measurement:
    """One replica of ``meas`` made by ``model``: same command and trajectory, the log's sensor
    (and ``disturbance_nm``, shape (n,), on the load when given)."""
    dt = meas.dt_s
    J = float(model.params.get("inertia.J", 1.0))
    K = float(model.gain_nm_per_v)
    wc = 2.0 * math.pi * TRACKING_BANDWIDTH_HZ
    kp, kd = J * wc * wc / K, 2.0 * J * wc / K
    x0 = est.initial_states(np.array([0]))[0]
    span = (float(np.min(meas.theta_rad)) - 0.5, float(np.max(meas.theta_rad)) + 0.5)
    # The replica's drive is the log's: its tracking pull may ask beyond the log's command and
    # gets no more than the log's rail (the rig amplifier's at least).
    P = pack_params(model, dt, quantize=False, range_rad=span, rail_v=drive_rail_v(meas.u_v))
    u, th = _replay(
        P,
        np.ascontiguousarray(meas.u_v, dtype=float),
        np.ascontiguousarray(est.theta_rad, dtype=float),
        np.ascontiguousarray(est.omega_rad_s, dtype=float),
        np.zeros(meas.n) if disturbance_nm is None else np.ascontiguousarray(disturbance_nm, dtype=float),
        float(dt),
        np.ascontiguousarray(x0, dtype=float),
        kp,
        kd,
    )
    if sensor.white_noise_rad > 0:
        th = th + sensor.white_noise_rad * rng.standard_normal(th.size)
    q = sensor.encoder_step_rad
    if q > 0:
        # A random phase of the encoder grid: the replicas do not share one rounding pattern.
        phase = q * rng.random()
        th = q * np.floor((th - phase) / q + 0.5) + phase
    return Measurement(meas.t_s, u, th, f"{meas.source} (replica)")


def residual_floor(
    meas: Measurement,
    model: AxisModel,
    est: StateEstimate,
    k: int,
    max_lag: int,
    replicas: int = DEFAULT_REPLICAS,
    refit: bool = True,
    seed: int = 0,
    disturbance: bool = True,
) -> ResidualFloor:
    """Run the k-step residual pipeline on ``replicas`` replicas of ``meas`` made by ``model``.

    Parameters
    ----------
    meas, model : the measured run and the (fitted) model judged on it.
    est : the measured run's estimated states (trajectory to follow, regime masks).
    k : prediction horizon, samples. ``max_lag``: autocorrelation lags kept.
    refit : refit the model on every replica (a parametric bootstrap: the band then includes
        what fitting on this excitation leaves in the parameters), else predict with ``model``.
    disturbance : put the run's load disturbance (:func:`disturbance_amplitude`) on the replicas.
    """
    from tracker.workbench.compare.compare import predict_k_step
    from tracker.workbench.fit.fit import fit_model

    sensor = SensorNoise.from_log(meas.theta_rad)
    masks = regime_masks(est.omega_rad_s, est.alpha_rad_s2, meas.dt_s, k)
    rng = np.random.default_rng(seed)
    amp = disturbance_amplitude(meas, model, est, k * meas.dt_s, sensor) if disturbance else None
    rms = np.empty(replicas)
    acs = np.empty((replicas, max_lag + 1))
    reg: dict[str, list[float]] = {name: [] for name in REGIME_NAMES}
    for r in range(replicas):
        dist = disturbance_draw(amp, meas.n, rng) if amp is not None else None
        rep = replay_run(meas, model, est, sensor, rng, dist)
        est_r = estimate_states(rep, model)
        m_r = model
        if refit:
            m_r = fit_model(rep, model, horizon_s=k * meas.dt_s, states=est_r).model
        e_r = with_load_observer(est_r, m_r, rep)
        resid = rep.theta_rad - predict_k_step(rep, m_r, e_r, k)
        resid[:k] = 0.0  # no full window before sample k (the measured residual is cut alike)
        rms[r] = float(np.sqrt(np.mean(resid[k:] ** 2)))
        acs[r] = autocorrelation(resid[k:], max_lag)
        for name in REGIME_NAMES:
            sel = masks[name][k:]
            reg[name].append(float(np.sqrt(np.mean(resid[k:][sel] ** 2))) if sel.any() else 0.0)
    d_rms = disturbance_rms_nm(amp, meas.n) if amp is not None else 0.0
    return ResidualFloor(sensor, rms, acs, {n: np.array(v) for n, v in reg.items()}, refit, d_rms)


__all__ = [
    "DEFAULT_REPLICAS",
    "ResidualFloor",
    "SensorNoise",
    "disturbance_amplitude",
    "disturbance_draw",
    "disturbance_rms_nm",
    "replay_run",
    "residual_floor",
]
