"""Compare a model with a measurement: k-step-ahead prediction (or free simulation), fit %, RMS.

The plant integrates, so a free simulation of 30 s drifts away on the smallest friction error
and its fit says little. The default is MATLAB ``compare`` with a prediction horizon: every
sample θ(t) is predicted from the estimated state at t−k and the measured command, k = horizon.

Default horizon: 30 ms. Long enough for a torque error to show above the encoder count (a
10 % Coulomb error on the pan axis moves the angle by δτ·h²/2J ≈ 4 counts in 30 ms, and every
sample adds evidence), to span a 14 ms transport delay and more than half a 20 Hz belt period;
short enough that the error from the estimated initial velocity (≈0.01 rad/s → 0.3 mrad) stays
small and the fit keeps weighting the fast dynamics the model must get right. On the EMPS data
the fitted parameters move by less than their standard errors between 10 and 50 ms (see
docs/workbench.md); 30 ms is in the middle of that plateau.

Two fit numbers, both 100·(1 − ‖y − ŷ‖/‖y − mean(y)‖):

* ``fit_percent`` on θ itself, as MATLAB's ``compare`` reports it. With k-step prediction it is
  high (99 % +) for any sensible model, because θ's variance is large next to k-step errors.
* ``fit_percent_increment`` on the increments over the horizon, y = θ(t) − θ(t−k),
  ŷ = θ̂(t | t−k) − θ(t−k). The same errors divided by what the model had to predict: this is
  the sensitive number to rank models and effects on.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.errors import ConfigError, DataError
from tracker.plant.effects.saturation import drive_rail_v
from tracker.plant.model import AxisModel
from tracker.plant.simulate import STATE_SIZE, advance, pack_params, simulate
from tracker.workbench.compare.consistency import ResidualVerdict, judge_residual
from tracker.workbench.compare.floor import DEFAULT_REPLICAS, residual_floor
from tracker.workbench.compare.regimes import RegimeBreakdown, RegimeError, break_down
from tracker.workbench.compare.residuals import ResidualAnalysis, analyse_residuals
from tracker.workbench.fit.torques import residual_torque_nm
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.states import StateEstimate, estimate_states, with_load_observer

FloatArray = NDArray[np.float64]
CompareMode = Literal["k_step", "free"]

DEFAULT_HORIZON_S = 0.03


def fit_percent(y: FloatArray, y_hat: FloatArray) -> float:
    """MATLAB ``compare`` fit: 100·(1 − ‖y − ŷ‖ / ‖y − mean(y)‖), in percent (can be negative)."""
    y = np.asarray(y, dtype=float)
    den = float(np.linalg.norm(y - y.mean()))
    if den == 0.0:
        return 0.0 if float(np.linalg.norm(y - y_hat)) > 0 else 100.0
    return 100.0 * (1.0 - float(np.linalg.norm(y - y_hat)) / den)


@dataclass(frozen=True, slots=True)
class CompareResult:
    """A model set against a measurement. Arrays have shape (n,).

    ``theta_pred_rad`` is the prediction of every sample (k steps ahead, or free simulation);
    ``residual_rad`` = measured − predicted. ``torque_residual_nm`` is the inverse-dynamics
    residual torque along the estimated states (what a missing torque effect looks like).
    ``rms_deg`` is the residual RMS in degrees (for a linear axis: the number ×180/π of metres,
    see ``rms_rad``).
    """

    fit_percent: float
    fit_percent_increment: float
    rms_deg: float
    rms_rad: float
    horizon_s: float | None
    mode: str
    t_s: FloatArray
    theta_meas_rad: FloatArray
    theta_pred_rad: FloatArray
    residual_rad: FloatArray
    torque_residual_nm: FloatArray
    regimes: Mapping[str, RegimeError]
    breakdown: RegimeBreakdown
    residuals: ResidualAnalysis
    states: StateEstimate = field(repr=False)
    verdict: ResidualVerdict | None = None

    def to_dict(self, arrays: bool = False) -> dict[str, object]:
        """JSON-ready: ``{"fit_percent", "rms_deg", "regimes": {...}, ...}`` (arrays if asked)."""
        out: dict[str, object] = {
            "fit_percent": self.fit_percent,
            "fit_percent_increment": self.fit_percent_increment,
            "rms_deg": self.rms_deg,
            "rms_rad": self.rms_rad,
            "horizon_s": self.horizon_s,
            "mode": self.mode,
            "regimes": {k: v.to_dict() for k, v in self.regimes.items()},
        }
        bd = self.breakdown.to_dict()
        out["position_bins"] = bd["position_bins"]
        out["time_segments"] = bd["time_segments"]
        out["frequency_bands_percent"] = bd["frequency_bands_percent"]
        out["residual_analysis"] = self.residuals.to_dict(arrays)
        if self.verdict is not None:
            out["residual_verdict"] = self.verdict.to_dict(arrays)
        if arrays:
            out.update(
                t_s=self.t_s.tolist(),
                theta_meas_rad=self.theta_meas_rad.tolist(),
                theta_pred_rad=self.theta_pred_rad.tolist(),
                residual_rad=self.residual_rad.tolist(),
            )
        return out


@njit(cache=True)
def _k_step_predict(P: FloatArray, u: FloatArray, dt: float, x0s: FloatArray, k: int) -> FloatArray:
    """θ̂(t | t−k) for every t (from sample 0 for t < k). Shape (n,)."""
    n = u.shape[0]
    out = np.empty(n)
    x = np.empty(STATE_SIZE)
    for t in range(n):
        s = t - k if t >= k else 0
        x[:] = x0s[s]
        for i in range(s, t):
            advance(x, P, u, i, dt, 0.0)
        out[t] = x[0]
    return out


def horizon_samples(horizon_s: float | None, dt_s: float, n: int) -> int:
    """The horizon in samples (default :data:`DEFAULT_HORIZON_S`), at least 1, at most n/4."""
    h = DEFAULT_HORIZON_S if horizon_s is None else float(horizon_s)
    if not (math.isfinite(h) and h > 0):
        raise ConfigError(f"prediction horizon must be a positive number of seconds, got {horizon_s!r}")
    k = max(1, int(round(h / dt_s)))
    if k > n // 4:
        raise DataError(f"prediction horizon {h:g} s is longer than a quarter of the log ({n * dt_s:g} s)")
    return k


def predict_k_step(meas: Measurement, model: AxisModel, est: StateEstimate, k: int) -> FloatArray:
    """k-step-ahead prediction of every sample from the estimated states. Shape (n,)."""
    P = pack_params(model, meas.dt_s, quantize=False, rail_v=drive_rail_v(meas.u_v))
    x0s = est.initial_states(np.arange(meas.n))
    return _k_step_predict(P, np.ascontiguousarray(meas.u_v, dtype=float), float(meas.dt_s), x0s, int(k))


@dataclass(frozen=True, slots=True)
class Score:
    """The headline numbers of a k-step comparison (no breakdown): what the fitter reports."""

    fit_percent: float
    fit_percent_increment: float
    rms_deg: float


def score_model(meas: Measurement, model: AxisModel, est: StateEstimate, k: int) -> Score:
    """Fit %, increment fit % and RMS (deg) of ``model``'s k-step prediction of ``meas``."""
    e = with_load_observer(est, model, meas)
    y_hat = predict_k_step(meas, model, e, k)
    y = meas.theta_rad
    return Score(
        fit_percent(y, y_hat),
        fit_percent(y[k:] - e.theta_rad[:-k], y_hat[k:] - e.theta_rad[:-k]),
        math.degrees(float(np.sqrt(np.mean((y - y_hat) ** 2)))),
    )


def compare_model(
    meas: Measurement,
    model: AxisModel,
    horizon_s: float | None = None,
    mode: CompareMode = "k_step",
    states: StateEstimate | None = None,
    replicas: int = 0,
) -> CompareResult:
    """Set ``model`` against ``meas``.

    Parameters
    ----------
    meas : measured log (t s, u V, θ rad).
    model : the model to compare.
    horizon_s : prediction horizon for ``mode="k_step"`` (default 0.03 s); in ``"free"`` mode
        it only sets the span of ``fit_percent_increment``.
    mode : "k_step" (default) or "free" (one simulation from the first estimated state).
    states : precomputed :func:`estimate_states` of ``meas`` (the load side is re-observed for
        ``model``); computed when None.
    replicas : when > 0 (k-step mode), judge the residual against that many simulated replicas
        of the run made by ``model`` (:mod:`~tracker.workbench.compare.consistency`): a few
        seconds more; ``CompareResult.verdict`` says whether a right model would leave it.

    Returns
    -------
    CompareResult
    """
    if mode not in ("k_step", "free"):
        raise ConfigError(f"compare mode must be 'k_step' or 'free', got {mode!r}")
    dt = meas.dt_s
    k = horizon_samples(horizon_s, dt, meas.n)
    est = estimate_states(meas, model) if states is None else with_load_observer(states, model, meas)
    y = meas.theta_rad
    if mode == "k_step":
        y_hat = predict_k_step(meas, model, est, k)
        base = est.theta_rad
        reg_k = k
    else:
        sim = simulate(model, meas.u_v, dt, x0=est.initial_states(np.array([0]))[0], quantize=False)
        y_hat = sim.theta_rad
        base = y_hat
        reg_k = 0
    resid = y - y_hat
    inc_y = y[k:] - (base[:-k] if mode == "k_step" else y[:-k])
    inc_hat = y_hat[k:] - base[:-k]
    rms = float(np.sqrt(np.mean(resid**2)))
    bd = break_down(resid, est.theta_rad, est.omega_rad_s, est.alpha_rad_s2, meas.t_s, reg_k)
    max_lag = int(min(max(5, round(max(0.1, 2 * k * dt) / dt)), max(5, meas.n // 4)))
    verdict = None
    if replicas > 0 and mode == "k_step":
        try:
            floor = residual_floor(meas, model, est, k, max_lag, replicas=replicas)
        except ConfigError:
            # A log no physical axis could make (the replicas' refit leaves the parameter
            # bounds): the comparison stands, the residual test has nothing to judge against.
            floor = None
        verdict = judge_residual(resid, est, k, floor) if floor is not None else None
    return CompareResult(
        fit_percent=fit_percent(y, y_hat),
        fit_percent_increment=fit_percent(inc_y, inc_hat),
        rms_deg=math.degrees(rms),
        rms_rad=rms,
        horizon_s=k * dt if mode == "k_step" else None,
        mode=mode,
        t_s=meas.t_s,
        theta_meas_rad=y,
        theta_pred_rad=y_hat,
        residual_rad=resid,
        torque_residual_nm=residual_torque_nm(meas, est, model),
        regimes=bd.regimes,
        breakdown=bd,
        residuals=analyse_residuals(resid, meas.u_v, dt, max_lag_s=max(0.1, 2 * k * dt)),
        states=est,
        verdict=verdict,
    )


__all__ = [
    "DEFAULT_HORIZON_S",
    "DEFAULT_REPLICAS",
    "CompareMode",
    "CompareResult",
    "Score",
    "score_model",
    "compare_model",
    "fit_percent",
    "horizon_samples",
    "predict_k_step",
]
