"""Refit every free parameter of a model to a measurement, in physical units, with uncertainties.

The loop, in order:

1. Estimate θ, ω, α at every sample (:mod:`tracker.workbench.measurements.states`).
2. Discrete and strongly nonlinear parameters by search: ripple cycles per revolution from the
   residual torque's spectrum over θ; delay, saturation limit and Stribeck velocity on a grid
   of the inverse-dynamics error; backlash width and belt frequency on a grid of the prediction
   error.
3. Starting values from the data itself: linear inverse-dynamics least squares
   (:mod:`tracker.workbench.fit.torques`) for J, b, Fc, asymmetries, offset, gravity, ripple. This
   makes the fit independent of the preset's units (EMPS is metres and newtons).
4. Nonlinear least squares (``scipy.optimize.least_squares``, trust region with the catalogue's
   bounds) on k-step-ahead prediction errors over consecutive windows (multiple shooting with
   the window start states from the smoother, the hidden load side from the model's observer).
   Parameters are scaled by their starting magnitude; gravity and ripple are fitted as
   (T cos φ, T sin φ) so the phase never wraps.
5. Standard errors: Gauss–Newton sandwich covariance with windows grouped into clusters longer
   than the residual correlation time (cluster-robust, so correlated residuals — the closed
   loop, disturbances — do not make the errors look smaller than they are).

``method="inverse_dynamics"`` stops after step 3 (the published EMPS identification method).
Dynamics depend only on torque/K, so K and J cannot both be free: with ``fit_gain`` K is fitted
and J is held.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from tracker.errors import ConfigError, JobCancelled
from tracker.plant.effects import get_param
from tracker.plant.effects.saturation import drive_rail_v
from tracker.plant.model import AxisModel
from tracker.plant.simulate import predict_windows
from tracker.workbench.compare.compare import horizon_samples, score_model
from tracker.workbench.fit.search import FINE_GRID, HIDDEN_STATE_PARAMS, grid_on_prediction, search_start
from tracker.workbench.fit.short import ShortFit, StopRule, short_least_squares
from tracker.workbench.fit.torques import replace_params
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.observed import predict_observed
from tracker.workbench.measurements.states import StateEstimate, encoder_step_rad, estimate_states

FloatArray = NDArray[np.float64]
FitMethod = Literal["k_step", "inverse_dynamics"]

MAX_EVALUATIONS = 400
# Short fits from the other basins of a multimodal start: evaluations, and windows kept (1 in n).
PROBE_EVALUATIONS = 25
PROBE_STRIDE = 4
# Every basin's short fit first gets this many evaluations; only those whose cost is then
# within PROBE_KEEP_RATIO of the best go on to PROBE_EVALUATIONS (a basin hundreds of times
# worse after its base parameters were refitted once or twice is not where the answer is).
PROBE_SCREEN_EVALUATIONS = 6
PROBE_KEEP_RATIO = 1.5
# A screen is stopped when, at its last rate of improvement, it would still end this many
# times beyond the keep ratio of the best screen so far (:class:`_HopelessScreen`).
SCREEN_HOPELESS_MARGIN = 10.0
# Screens that end this close (every scaled coordinate, relative) are one basin: one trial.
SAME_POINT_TOLERANCE = 0.02
# Short fits from rival minima (a checked delay), and the z a rival's excess cost must reach
# to be rejected (two-sided 95 %).
RIVAL_EVALUATIONS = 8
RIVAL_Z = 1.96
POINTS_PER_WINDOW = 10
STDERR_STEP = 1e-2
DIFF_STEP = 1e-2
COARSE_DIFF_STEP = 2e-2
FINE_DIFF_STEP = 1e-3
# Residuals are grouped in clusters of at least this many seconds for the standard errors.
MIN_CLUSTER_S = 0.25
MIN_CLUSTERS = 12
# Parameter pairs more correlated than this are reported as not separable.
CORRELATION_WARNING = 0.95
# ... and at least one of the pair is uncertain by more than this fraction of its value.
UNCERTAIN_FRACTION = 0.1
# The default horizon is lengthened on a coarse encoder until the windows' mean displacement is
# this many counts: a displacement read by two encoder readings (each ±q/2, together σ = q/√6) is
# then known to the relative precision a parameter is wanted to (:func:`fit_horizon_samples`) ...
MIN_WINDOW_COUNTS = (1.0 / math.sqrt(6.0)) / UNCERTAIN_FRACTION
# ... up to this many times the default horizon (a disturbance accumulates over longer windows).
MAX_HORIZON_STRETCH = 4
# Typical magnitudes of parameters that may start at exactly zero (the optimizer's unit step).
ZERO_START_SCALES = {"gravity.phase": 1.0, "ripple.phase": 1.0, "delay.seconds": 1e-3, "backlash.width": 1e-3}
# Components fitted instead of (amplitude, phase).
_POLAR = {"gravity": ("gravity.torque", "gravity.phase"), "ripple": ("ripple.amplitude", "ripple.phase")}


@dataclass(frozen=True, slots=True)
class FitResult:
    """A refitted model.

    ``params`` has every parameter of the model (SI units); ``stderr`` the standard error of
    each fitted one (cluster-robust, SI units). ``fit_percent``/``fit_percent_increment``/
    ``rms_deg`` are k-step-ahead figures of the refitted model at ``horizon_s`` (see
    :mod:`tracker.workbench.compare.compare`). ``cost`` is ½Σr² of the final window residuals (rad²);
    ``start_params`` the starting values the nonlinear fit began from.
    """

    model: AxisModel
    params: dict[str, float]
    stderr: dict[str, float]
    fit_percent: float
    fit_percent_increment: float
    rms_deg: float
    cost: float
    n_evaluations: int
    converged: bool
    free: tuple[str, ...] = ()
    horizon_s: float = 0.0
    method: str = "k_step"
    start_params: dict[str, float] = field(default_factory=dict)
    inverse_dynamics_error_percent: float = math.nan
    elapsed_s: float = 0.0
    correlated: tuple[tuple[str, str, float], ...] = ()
    # The horizon the parameters were fitted over (longer than ``horizon_s`` on a coarse encoder
    # when none was asked: :func:`fit_horizon_samples`); the fit % is reported at ``horizon_s``.
    fit_horizon_s: float = 0.0
    # Upper bounds this log sets below the catalogue's: a saturation's limit at the log's drive
    # rail (:func:`drive_rail_v`) clips nothing (:func:`parameter_certainty` flags it there).
    upper_bounds: dict[str, float] = field(default_factory=dict)

    @property
    def warnings(self) -> tuple[str, ...]:
        """Plain-language notes: parameters the data cannot tell apart, a fit that did not converge."""
        notes = [
            f"{a} and {b} are {abs(c):.3f} correlated: this run cannot tell them apart"
            for a, b, c in self.correlated
        ]
        if not self.converged:
            notes.append("the fit did not converge; the parameters may be far from the best")
        return tuple(notes)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: ``{"fit_percent", "params", "stderr", ...}``."""
        return {
            "fit_percent": self.fit_percent,
            "fit_percent_increment": self.fit_percent_increment,
            "rms_deg": self.rms_deg,
            "params": dict(self.params),
            "stderr": dict(self.stderr),
            "gain_nm_per_v": self.model.gain_nm_per_v,
            "effects": list(self.model.effects),
            "free": list(self.free),
            "cost": self.cost,
            "n_evaluations": self.n_evaluations,
            "converged": self.converged,
            "horizon_s": self.horizon_s,
            "fit_horizon_s": self.fit_horizon_s,
            "method": self.method,
            "inverse_dynamics_error_percent": self.inverse_dynamics_error_percent,
            "elapsed_s": self.elapsed_s,
            "correlated": [list(c) for c in self.correlated],
            "warnings": list(self.warnings),
        }


def default_free(model: AxisModel, fit_gain: bool = False) -> tuple[str, ...]:
    """Parameters fitted by default: ``Param.fit`` ones, without the encoder step (read from the
    data); J leaves the set when the gain is fitted. Ripple cycles are searched first (spectrum,
    then starts a line width apart), then fitted as a real number with the rest."""
    names = [k for k in model.free_param_names() if k != "quantization.step"]
    if fit_gain:
        names = [k for k in names if k != "inertia.J"]
    return tuple(names)


def _log_upper_bounds(rail_v: float) -> dict[str, float]:
    """Upper bounds a log whose drive's rail is ``rail_v`` (V) sets below the catalogue's: a
    saturation's limit no higher than the rail (above it the limit clips nothing the log
    commands)."""
    return {"saturation.limit": rail_v}


def _bounds(name: str, rail_v: float) -> tuple[float, float]:
    """The bounds of parameter ``name`` in a fit to a log whose drive's rail is ``rail_v`` (V):
    the catalogue's, lowered by :func:`_log_upper_bounds`."""
    prm = get_param(name)
    return prm.lower, min(prm.upper, _log_upper_bounds(rail_v).get(name, math.inf))


@dataclass(frozen=True, slots=True)
class _Coords:
    """Optimizer coordinates: scaled parameters, (cos, sin) components, and the gain."""

    names: tuple[str, ...]
    scale: FloatArray
    lower: FloatArray
    upper: FloatArray
    rail_v: float  # the log's drive rail (:func:`drive_rail_v`): bounds a saturation's limit

    @classmethod
    def build(cls, model: AxisModel, free: Sequence[str], fit_gain: bool, rail_v: float) -> _Coords:
        names: list[str] = []
        lo: list[float] = []
        hi: list[float] = []
        scale: list[float] = []
        p = model.params
        for k in free:
            eff = k.split(".")[0]
            if eff in _POLAR and k == _POLAR[eff][1] and _POLAR[eff][0] in free:
                continue  # the phase goes with the amplitude's components
            if eff in _POLAR and k == _POLAR[eff][0]:
                amp = max(abs(p[k]), 1e-3 * _torque_scale(model))
                for comp in (".cos", ".sin"):
                    names.append(eff + comp)
                    lo.append(-np.inf)
                    hi.append(np.inf)
                    scale.append(amp)
                continue
            names.append(k)
            bounds = _bounds(k, rail_v)
            lo.append(bounds[0])
            hi.append(bounds[1])
            scale.append(_param_scale(model, k))
        if fit_gain:
            names.append("gain")
            lo.append(1e-12)
            hi.append(np.inf)
            scale.append(model.gain_nm_per_v)
        s = np.array(scale)
        return cls(tuple(names), s, np.array(lo) / s, np.array(hi) / s, rail_v)

    def encode(self, model: AxisModel) -> FloatArray:
        p = model.params
        x = np.empty(len(self.names))
        for i, n in enumerate(self.names):
            if n == "gain":
                v = model.gain_nm_per_v
            elif n.endswith(".cos") or n.endswith(".sin"):
                amp_k, ph_k = _POLAR[n.split(".")[0]]
                f = math.cos if n.endswith(".cos") else math.sin
                v = p[amp_k] * f(p[ph_k])
            else:
                v = p[n]
            x[i] = v / self.scale[i]
        return np.clip(x, self.lower, self.upper)

    def values(self, x: FloatArray) -> tuple[dict[str, float], float | None]:
        vals = {n: float(xi * s) for n, xi, s in zip(self.names, x, self.scale, strict=True)}
        gain = vals.pop("gain", None)
        # x at a bound times the scale can round a hair past the catalogue's bound (0.5 Hz
        # came back as 0.49999999999999994 and the model refused it).
        for n in self.names:
            if n in vals and not n.endswith((".cos", ".sin")):
                lower, upper = _bounds(n, self.rail_v)
                vals[n] = min(max(vals[n], lower), upper)
        for eff, (amp_k, ph_k) in _POLAR.items():
            if eff + ".cos" in vals:
                c, s = vals.pop(eff + ".cos"), vals.pop(eff + ".sin")
                vals[amp_k] = math.hypot(c, s)
                vals[ph_k] = math.atan2(s, c)
        return vals, gain

    def decode(self, model: AxisModel, x: FloatArray) -> AxisModel:
        vals, gain = self.values(x)
        if gain is not None:
            return AxisModel.create(gain, {}, model.effects, {**model.params, **vals})
        return replace_params(model, vals)

    def correlated(
        self, cov: FloatArray, threshold: float = CORRELATION_WARNING
    ) -> tuple[tuple[str, str, float], ...]:
        """Pairs of coordinates whose estimates correlate beyond ``threshold`` (|ρ|)."""
        sd = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        rho = cov / np.outer(sd, sd)
        label = [n.rsplit(".", 1)[0] if n.endswith((".cos", ".sin")) else n for n in self.names]
        out = []
        for i in range(len(self.names)):
            for j in range(i + 1, len(self.names)):
                if label[i] != label[j] and abs(rho[i, j]) > threshold:
                    out.append((label[i], label[j], float(rho[i, j])))
        return tuple(out)

    def stderr(self, x: FloatArray, cov: FloatArray) -> dict[str, float]:
        """Standard errors in physical units (delta method for amplitude and phase)."""
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0)) * self.scale
        out: dict[str, float] = {}
        idx = {n: i for i, n in enumerate(self.names)}
        for n, i in idx.items():
            if n == "gain":
                out["gain_nm_per_v"] = float(sd[i])
            elif not n.endswith((".cos", ".sin")):
                out[n] = float(sd[i])
        for eff, (amp_k, ph_k) in _POLAR.items():
            if eff + ".cos" not in idx:
                continue
            i, j = idx[eff + ".cos"], idx[eff + ".sin"]
            c, s = x[i] * self.scale[i], x[j] * self.scale[j]
            sub = cov[np.ix_([i, j], [i, j])] * np.outer(self.scale[[i, j]], self.scale[[i, j]])
            a = math.hypot(c, s) or 1e-300
            g_amp = np.array([c / a, s / a])
            g_ph = np.array([-s / a**2, c / a**2])
            out[amp_k] = float(math.sqrt(max(g_amp @ sub @ g_amp, 0.0)))
            out[ph_k] = float(math.sqrt(max(g_ph @ sub @ g_ph, 0.0)))
        return out


def _poorly_separated(
    pairs: tuple[tuple[str, str, float], ...], stderr: Mapping[str, float], model: AxisModel
) -> tuple[tuple[str, str, float], ...]:
    """The correlated pairs where the correlation costs precision (a relative standard error
    above UNCERTAIN_FRACTION): strongly correlated but sharp estimates are no cause for alarm."""

    def uncertain(name: str) -> bool:
        key = _POLAR[name][0] if name in _POLAR else name
        value = abs(model.params.get(key, 0.0))
        se = stderr.get(key, 0.0)
        return value == 0.0 or se > UNCERTAIN_FRACTION * value

    return tuple(p for p in pairs if uncertain(p[0]) or uncertain(p[1]))


def fit_horizon_samples(meas: Measurement, k: int) -> int:
    """The horizon the fit predicts over when the user chose none: ``k``, or longer on a coarse
    encoder.

    Each window's information is the displacement the model predicts from its start state. On a
    coarse encoder a 30 ms window moves a count or two, the same size as the reading's own error
    (two readings, each ±q/2) and as the start state's error from quantized data, and the fit
    trades the inertia against them: on 500-count logs of an independent generator the inertia
    came out 11-400 % off with standard errors of 3-6 % (issue 9, session 8). The horizon grows
    until the windows' mean displacement is :data:`MIN_WINDOW_COUNTS` counts, at most
    :data:`MAX_HORIZON_STRETCH` times ``k`` and a quarter of the log; an unquantized log keeps ``k``.
    """
    q = encoder_step_rad(meas.theta_rad)
    if q <= 0.0:
        return k
    theta = np.asarray(meas.theta_rad, dtype=float)
    longest = min(MAX_HORIZON_STRETCH * k, max(k, meas.n // 4))
    for kk in range(k, longest + 1):
        if float(np.mean(np.abs(theta[kk:] - theta[:-kk]))) >= MIN_WINDOW_COUNTS * q:
            return kk
    return longest


def _torque_scale(model: AxisModel) -> float:
    """A typical torque of the axis: the Coulomb torque, or K·1 V."""
    return max(model.params["coulomb.torque"], 1e-3 * model.gain_nm_per_v)


def _param_scale(model: AxisModel, name: str) -> float:
    v = abs(model.params[name])
    if v > 0:
        return v
    if name == "offset.torque":
        return 0.1 * _torque_scale(model)
    if name in ZERO_START_SCALES:
        return ZERO_START_SCALES[name]
    prm = get_param(name)
    return max(abs(prm.default), 1e-6 * (prm.upper - prm.lower), 1e-12)


def window_starts(n: int, k: int) -> NDArray[np.int64]:
    """Starts of consecutive windows of k steps covering the log (multiple shooting). Shape (m,)."""
    return np.arange(0, n - k - 1, k, dtype=np.int64)


def _cluster_ids(window_resid: FloatArray, dt_window_s: float) -> NDArray[np.int64]:
    """Group windows into clusters longer than the residual's correlation time."""
    m = window_resid.shape[0]
    mean_w = window_resid.mean(axis=1)
    z = mean_w - mean_w.mean()
    corr_len = 1
    if np.any(z):
        ac = np.correlate(z, z, mode="full")[m - 1 :]
        ac = ac / ac[0]
        below = np.flatnonzero(ac < math.exp(-2.0))
        corr_len = int(below[0]) if below.size else m
    size = max(corr_len, int(math.ceil(MIN_CLUSTER_S / dt_window_s)), 1)
    size = min(size, max(1, m // MIN_CLUSTERS))
    ids: NDArray[np.int64] = np.arange(m, dtype=np.int64) // size
    return ids


def _robust_covariance(
    jac: FloatArray, resid: FloatArray, clusters: NDArray[np.int64], per_window: int
) -> FloatArray:
    """Cluster-robust sandwich (JᵀJ)⁻¹ (Σ_c g_c g_cᵀ) (JᵀJ)⁻¹ with g_c = J_cᵀ r_c."""
    p = jac.shape[1]
    jtj = jac.T @ jac
    bread = np.linalg.pinv(jtj)
    rows = np.repeat(clusters, per_window)
    g = np.zeros((int(clusters.max()) + 1, p))
    np.add.at(g, rows, jac * resid[:, None])
    c = g.shape[0]
    meat = g.T @ g * (c / max(c - 1, 1))
    sandwich: FloatArray = bread @ meat @ bread
    return sandwich


def _central_jacobian(
    fun: Callable[[FloatArray], FloatArray],
    x: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    f0: FloatArray,
) -> FloatArray:
    """Jacobian of ``fun`` at ``x`` by central differences of ±STDERR_STEP (one-sided at a bound)."""
    jac = np.empty((f0.size, x.size))
    for i in range(x.size):
        h = STDERR_STEP * max(abs(float(x[i])), 1e-3)
        lo, hi = x.copy(), x.copy()
        lo[i] = max(x[i] - h, lower[i])
        hi[i] = min(x[i] + h, upper[i])
        f_lo = fun(lo) if lo[i] != x[i] else f0
        f_hi = fun(hi) if hi[i] != x[i] else f0
        span = hi[i] - lo[i]
        jac[:, i] = (f_hi - f_lo) / span if span > 0 else 0.0
    return jac


def _inflated_gauss_newton(jac: FloatArray, resid: FloatArray) -> FloatArray:
    """s²(JᵀJ)⁻¹ inflated by τ = 1 + 2Σρ_k, the residuals' integrated autocorrelation
    (N/τ is the effective number of independent residuals)."""
    n, p = jac.shape
    s2 = float(resid @ resid) / max(n - p, 1)
    z = resid - resid.mean()
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfft(z, nfft)
    ac = np.fft.irfft(f * np.conj(f), nfft)[: max(2, n // 10)]
    rho = ac / ac[0] if ac[0] > 0 else np.zeros_like(ac)
    neg = np.flatnonzero(rho[1:] <= 0.0)
    stop = int(neg[0]) + 1 if neg.size else rho.size
    tau = max(1.0, 1.0 + 2.0 * float(np.sum(rho[1:stop])))
    cov: FloatArray = np.linalg.pinv(jac.T @ jac) * s2 * tau
    return cov


def parameter_covariance(
    jac: FloatArray, resid: FloatArray, clusters: NDArray[np.int64], per_window: int
) -> FloatArray:
    """Covariance of the fitted coordinates: the cluster-robust sandwich, with each standard
    error raised to at least the autocorrelation-inflated Gauss–Newton one.

    The sandwich is right on average but, with a dozen clusters, itself noisy: on a bad draw
    it collapses along one direction (a 22 % error reported as ±0.3 %). The floor keeps that
    from happening; correlations come from the sandwich.
    """
    sand = _robust_covariance(jac, resid, clusters, per_window)
    gn = _inflated_gauss_newton(jac, resid)
    sd_s = np.sqrt(np.maximum(np.diag(sand), 1e-300))
    sd = np.maximum(sd_s, np.sqrt(np.maximum(np.diag(gn), 0.0)))
    scale = sd / sd_s
    out: FloatArray = sand * np.outer(scale, scale)
    return out


def _widened_for_rivals(
    coords: _Coords,
    probe: Callable[[FloatArray], FloatArray],
    x_best: FloatArray,
    rivals: Sequence[FloatArray],
    stderr: Mapping[str, float],
    per_window: int,
    window_s: float,
) -> dict[str, float]:
    """Standard errors at least half the distance to a rival minimum the data cannot reject.

    The local standard errors describe one basin. When another (a delay of 0.5 ms against 6 ms
    with stiction, a second belt resonance) fits the same windows about as well, the data do
    not decide between them, and ±0.3 ms around 6 ms would be a confident wrong answer. The
    comparison is Vuong's test of non-nested models on the windows' sums of squares: the
    rival's excess D = Σ_w (S_rival,w − S_best,w) against its spread over clusters of windows
    longer than the residuals' correlation time; |z| < 1.96 is a rival the data cannot reject.
    """
    f_best = probe(x_best).reshape(-1, per_window)
    s_best = np.sum(f_best * f_best, axis=1)
    clusters = _cluster_ids(f_best, window_s)
    best_vals, _ = coords.values(x_best)
    out = dict(stderr)
    for x in rivals:
        f = probe(x).reshape(-1, per_window)
        d = np.bincount(clusters, weights=np.sum(f * f, axis=1) - s_best)
        c = d.size
        spread = math.sqrt(c * float(np.var(d)) * c / max(c - 1, 1)) if c > 1 else 0.0
        if not float(d.sum()) < RIVAL_Z * spread:
            continue
        vals, _ = coords.values(x)
        for name, v in vals.items():
            if name not in out:
                continue
            delta = v - best_vals[name]
            if name.endswith(".phase"):
                delta = math.remainder(delta, 2.0 * math.pi)
            out[name] = max(out[name], 0.5 * abs(delta))
    return out


def _diff_step(name: str) -> float:
    """Relative finite-difference step of a coordinate."""
    if name == "backlash.width":
        return COARSE_DIFF_STEP
    if name == "ripple.cycles_per_rev":
        # 1 % of 30 cycles turns the phase at the end of a 1.6 rad span by 0.5 rad: far past
        # where the cost is linear. 0.1 % moves it by 0.05 rad.
        return FINE_DIFF_STEP
    return DIFF_STEP


@dataclass(slots=True)
class _HopelessScreen:
    """A screen's stop rule (:func:`~tracker.workbench.fit.short.short_least_squares`): stops a
    screen that cannot survive.

    After each iteration the screen's cost is extrapolated at its last rate of improvement
    over the evaluations it has left; when even that ends more than SCREEN_HOPELESS_MARGIN
    times beyond the keep ratio of the best finished screen (``bar``), it stops (a stiff belt
    whose cost moves 2 % an iteration, 450 times above the resonance's, took a quarter of
    the fit). Screens that fall steeply (250 times above the bar, then halving each
    iteration) run on.
    """

    last_cost: float
    bar: float
    evaluations: int

    def __call__(self, x: FloatArray, cost: float, nfev: int) -> bool:
        left = self.evaluations - nfev
        rate = self.last_cost / cost if cost > 0.0 else math.inf
        self.last_cost = cost
        if left <= 0 or not math.isfinite(self.bar) or not rate < 1e6:
            return False
        projected = cost / max(rate, 1.0) ** left
        return projected > SCREEN_HOPELESS_MARGIN * PROBE_KEEP_RATIO * self.bar


@dataclass(frozen=True, slots=True)
class _TrialStop:
    """A trial's stop rule: on a hidden-state bound once a trial has finished inside the
    model's domain (``bound_loses``, :func:`_at_a_bound`), or where an earlier trial ended
    (``ends``, :func:`_same_point`): two trials in one basin are one trial, and the one that
    runs into the other's end would only repeat it (on a 2 kHz belt log two of three trials
    spent 130 evaluations walking to the first one's end point)."""

    coords: _Coords
    bound_loses: bool
    ends: tuple[FloatArray, ...]

    def __call__(self, x: FloatArray, cost: float, nfev: int) -> bool:
        if self.bound_loses and _at_a_bound(self.coords, x):
            return True
        return any(_same_point(x, end) for end in self.ends)


def _same_point(a: FloatArray, b: FloatArray) -> bool:
    """Whether two optimizer points agree within SAME_POINT_TOLERANCE in every scaled
    coordinate (relative to its size, or absolutely near zero)."""
    tol = SAME_POINT_TOLERANCE * np.maximum(np.maximum(np.abs(a), np.abs(b)), 1.0)
    return bool(np.all(np.abs(a - b) <= tol))


def _at_a_bound(coords: _Coords, x: FloatArray) -> bool:
    """Whether a hidden-state parameter (belt frequency or damping, backlash width) ended within
    1 % of a catalogue bound: a start whose short fit runs there has left the model's domain (a
    0.5 Hz belt with a tenfold J is a free load the observer steers, not a resonance found), so
    a start that stays inside wins over it whatever their costs."""
    for i, n in enumerate(coords.names):
        if n in HIDDEN_STATE_PARAMS:
            lo, hi, v = coords.lower[i], coords.upper[i], x[i]
            if v <= lo * 1.01 or (math.isfinite(hi) and v >= hi * 0.99):
                return True
    return False


def fit_model(
    meas: Measurement,
    model: AxisModel,
    free: Sequence[str] | None = None,
    horizon_s: float | None = None,
    fit_gain: bool = False,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    method: FitMethod = "k_step",
    states: StateEstimate | None = None,
) -> FitResult:
    """Refit the free parameters of ``model`` to ``meas``.

    Parameters
    ----------
    meas : measured log.
    model : structure (effects) and starting values; K is taken from it.
    free : parameters to fit (full names); default :func:`default_free`.
    horizon_s : prediction horizon of the fit and of the reported fit % (default 0.03 s).
    fit_gain : also fit K (J is then held: only torque/K is identifiable).
    progress : called with the fraction done (0..1) now and then.
    cancel : polled during the fit; returning True raises :class:`JobCancelled`.
    method : "k_step" (default) or "inverse_dynamics" (linear least squares only).
    states : precomputed :func:`estimate_states` of ``meas``.

    Returns
    -------
    FitResult
    """
    t0 = time.perf_counter()
    if method not in ("k_step", "inverse_dynamics"):
        raise ConfigError(f"fit method must be 'k_step' or 'inverse_dynamics', got {method!r}")
    free_t = default_free(model, fit_gain) if free is None else tuple(free)
    for name in free_t:
        if name not in model.params:
            raise ConfigError(
                f"cannot fit {name!r}: the model has no such parameter (it has {', '.join(model.params)})"
            )
    if fit_gain:
        free_t = tuple(n for n in free_t if n != "inertia.J")
    dt = meas.dt_s
    k_report = horizon_samples(horizon_s, dt, meas.n)
    k = k_report if horizon_s is not None else fit_horizon_samples(meas, k_report)
    est = estimate_states(meas) if states is None else states

    def check_cancel() -> None:
        if cancel is not None and cancel():
            raise JobCancelled("fit cancelled")

    check_cancel()
    start = search_start(meas, est, model, free_t, k)
    model0 = start.model
    if progress is not None:
        progress(0.1)
    if method == "inverse_dynamics" or not free_t:
        return _finish(
            meas,
            model0,
            est,
            k_report,
            free_t,
            {},
            0.0,
            0,
            True,
            method,
            start.model,
            start.id_error_percent,
            t0,
            fit_k=k,
        )

    coords = _Coords.build(model0, free_t, fit_gain, drive_rail_v(meas.u_v))
    starts = window_starts(meas.n, k)
    # Errors inside a window are smooth in time: ~10 points per window carry its information
    # and keep the least-squares algebra small; every window (every sample's dynamics) is simulated.
    every = max(1, k // POINTS_PER_WINDOW)
    cols = np.arange(every - 1, k, every)
    y_win = meas.theta_rad[starts[:, None] + 1 + cols[None, :]]
    u = np.ascontiguousarray(meas.u_v, dtype=float)
    two_mass = model0.has("backlash") or model0.has("compliance")
    noise = max(est.noise_rad, 1e-300)
    n_eval = 0

    def windowed(stride: int) -> Callable[[FloatArray], FloatArray]:
        """Residuals (every ``stride``-th window) as a function of the coordinates."""
        sel_starts, sel_y = starts[::stride], y_win[::stride]

        def residuals(x: FloatArray) -> FloatArray:
            nonlocal n_eval
            check_cancel()
            n_eval += 1
            if progress is not None and n_eval % 10 == 0:
                progress(min(0.95, 0.1 + 0.85 * n_eval / 150.0))
            m = coords.decode(model0, x)
            if two_mass:
                pred = predict_observed(m, meas, est, sel_starts, k + 1)[:, 1 + cols]
            else:
                x0s = est.initial_states(sel_starts)
                pred = predict_windows(m, u, dt, sel_starts, k + 1, x0s)[:, 1 + cols]
            r: FloatArray = ((sel_y - pred) / noise).ravel()
            return r

        return residuals

    residuals = windowed(1)

    x0 = coords.encode(model0)
    # Contact events make the backlash cost step-like at small scales: difference it coarsely.
    steps = np.array([_diff_step(n) for n in coords.names])

    def solve(start: FloatArray) -> Any:
        return least_squares(
            residuals,
            start,
            bounds=(coords.lower, coords.upper),
            method="trf",
            x_scale=1.0,
            diff_step=steps,
            xtol=1e-8,
            ftol=1e-8,
            max_nfev=MAX_EVALUATIONS,
        )

    probe = windowed(PROBE_STRIDE)
    tried: list[FloatArray] = []
    if start.alternatives:
        # Other basins of a multimodal parameter (a belt resonance): the grid judged them with the
        # base parameters not yet refitted. A short fit from each on a quarter of the windows,
        # then the full fit from the best.
        def short_fit(x: FloatArray, evaluations: int, stop: StopRule | None = None) -> ShortFit:
            hopeless = stop if isinstance(stop, _HopelessScreen) else None

            def fun(x_: FloatArray) -> FloatArray:
                r = probe(x_)
                if hopeless is not None and math.isnan(hopeless.last_cost):
                    hopeless.last_cost = 0.5 * float(r @ r)  # the start's (the first evaluation)
                return r

            return short_least_squares(fun, x, coords.lower, coords.upper, steps, evaluations, stop)

        x_starts = [coords.encode(cand) for cand in (model0, *start.alternatives)]
        screened: list[ShortFit] = []
        for x in x_starts:
            bar = min((t.cost for t in screened), default=math.inf)
            hopeless = _HopelessScreen(math.nan, bar, PROBE_SCREEN_EVALUATIONS)
            screened.append(short_fit(x, PROBE_SCREEN_EVALUATIONS, hopeless))
        best_screen = min(t.cost for t in screened)
        # Survivors of the screen, best first, one per basin: starts whose screens ended at the
        # same point (two starts in one basin, e.g. the same resonance from two sets of base
        # values) would only repeat each other's trial.
        kept: list[ShortFit] = []
        for first in sorted(screened, key=lambda t: t.cost):
            if first.cost <= PROBE_KEEP_RATIO * best_screen and not any(
                _same_point(first.x, o.x) for o in kept
            ):
                kept.append(first)
        if len(kept) == 1:
            # One basin left: the final fit goes on from where its screen stopped.
            x0 = kept[0].x
        else:
            trials: list[tuple[bool, float, FloatArray]] = []
            for first in kept:
                # A screen that used up its evaluations goes on for the rest of a trial's;
                # one that converged within them already is that trial.
                more = PROBE_EVALUATIONS - PROBE_SCREEN_EVALUATIONS
                # Once a trial has finished inside the model's domain, one that runs onto a
                # hidden-state bound has lost whatever its cost (:func:`_at_a_bound`): it stops
                # there (a belt damping run to its bound of 2 needs many sub-steps a sample).
                inside = any(not t[0] for t in trials)
                stop = _TrialStop(coords, inside, tuple(t[2] for t in trials))
                trial = short_fit(first.x, more, stop) if first.status == 0 else first
                trials.append((_at_a_bound(coords, trial.x), trial.cost, trial.x))
            x0 = min(trials, key=lambda t: (t[0], t[1]))[2]
    sol = solve(x0)
    if "backlash.width" in coords.names:
        # The width's cost is step-like; the first pass moved the other parameters. Search the
        # width again around its value with them in place, then polish everything once more.
        m1 = coords.decode(model0, sol.x)
        w1 = m1.params["backlash.width"]
        m2 = grid_on_prediction(meas, est, m1, "backlash.width", [w1 * f for f in FINE_GRID], k, stride=1)
        sol = solve(coords.encode(m2))
    fitted = coords.decode(model0, sol.x)
    resid = sol.fun * noise
    # The solver's Jacobian uses tiny forward steps: one stick/slip decision flipping inside a
    # window makes a huge spurious slope and the standard error collapse. Central differences
    # over ±1 % of each (scaled) coordinate average over such events.
    jac = _central_jacobian(residuals, sol.x, coords.lower, coords.upper, sol.fun) * noise
    clusters = _cluster_ids(resid.reshape(-1, cols.size), k * dt)
    cov = parameter_covariance(jac, resid, clusters, cols.size)
    stderr = coords.stderr(sol.x, cov)
    if start.rivals and "delay.seconds" in coords.names:
        # The rival delays are hypotheses (none, one sample, another minimum of the search's
        # profile): hold the delay there and refit the rest briefly. The belt's and the ripple's
        # other basins are starts, not hypotheses: their short fits choose where to begin.
        i_d = coords.names.index("delay.seconds")
        keep = np.arange(coords.names.__len__()) != i_d
        for cand in start.rivals:
            x_r = coords.encode(cand)

            def held(x_free: FloatArray, x_r: FloatArray = x_r) -> FloatArray:
                x_full = x_r.copy()
                x_full[keep] = x_free
                return probe(x_full)

            got = short_least_squares(
                held, x_r[keep], coords.lower[keep], coords.upper[keep], steps[keep], RIVAL_EVALUATIONS
            ).x
            x_full = x_r.copy()
            x_full[keep] = got
            tried.append(x_full)
    if tried:
        stderr = _widened_for_rivals(coords, probe, sol.x, tried, stderr, cols.size, PROBE_STRIDE * k * dt)
    return _finish(
        meas,
        fitted,
        est,
        k_report,
        free_t,
        stderr,
        0.5 * float(resid @ resid),
        n_eval + 0,
        bool(sol.success),
        method,
        model0,
        start.id_error_percent,
        t0,
        _poorly_separated(coords.correlated(cov), stderr, fitted),
        k,
    )


def _finish(
    meas: Measurement,
    model: AxisModel,
    est: StateEstimate,
    k: int,
    free: tuple[str, ...],
    stderr: Mapping[str, float],
    cost: float,
    n_eval: int,
    converged: bool,
    method: str,
    start_model: AxisModel,
    id_error: float,
    t0: float,
    correlated: tuple[tuple[str, str, float], ...] = (),
    fit_k: int | None = None,
) -> FitResult:
    fit_k = k if fit_k is None else fit_k
    score = score_model(meas, model, est, k)
    return FitResult(
        model=model,
        params=dict(model.params),
        stderr=dict(stderr),
        fit_percent=score.fit_percent,
        fit_percent_increment=score.fit_percent_increment,
        rms_deg=score.rms_deg,
        cost=cost,
        n_evaluations=n_eval,
        converged=converged,
        free=free,
        horizon_s=k * meas.dt_s,
        method=method,
        start_params=dict(start_model.params),
        inverse_dynamics_error_percent=id_error,
        elapsed_s=time.perf_counter() - t0,
        correlated=correlated,
        fit_horizon_s=fit_k * meas.dt_s,
        upper_bounds={
            k: v for k, v in _log_upper_bounds(drive_rail_v(meas.u_v)).items() if k in model.params
        },
    )


__all__ = ["FitMethod", "FitResult", "default_free", "fit_model", "window_starts"]
