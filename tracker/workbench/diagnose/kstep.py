"""k-step-ahead prediction scores for the diagnosis: judge and refine candidates by simulation.

The inverse-dynamics screening proposes; the simulator decides. Every candidate model is run
from the estimated state at many window starts over the prediction horizon with the measured
command, and its errors are compared window by window with the current model's (a paired
test over blocks of windows, so time-correlated errors are not counted as independent).
Hidden load states (backlash, compliance) start from a model-based load observer: the load's
equation of motion integrated along the smoothed motor trajectory (the belt/contact is damped,
so it forgets its unknown start within a few periods).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import optimize

from tracker.errors import JobCancelled
from tracker.plant.effects import get_param
from tracker.plant.effects.saturation import drive_rail_v
from tracker.plant.model import AxisModel
from tracker.plant.simulate import (
    I_BW,
    I_CC,
    I_CK,
    I_GPH,
    I_GT,
    I_JL,
    I_NSUB,
    I_TWO,
    STATE_SIZE,
    advance,
    pack_params,
    predict_windows,
)
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.idim import Signals

FloatArray = NDArray[np.float64]
DEFAULT_HORIZON_S = 0.03  # as tracker.workbench.compare.compare
TRIM_BLOCKS = 2  # blocks left out of the robust improvement
BACKLASH_STARTS = 5  # places in the dead band tried at each window start


@njit(cache=True)
def _load_observer(
    P: FloatArray, th_m: FloatArray, om_m: FloatArray, dt: float
) -> tuple[FloatArray, FloatArray]:
    """Integrate the load side (belt spring with dead band, gravity) driven by the motor."""
    n = th_m.shape[0]
    n_sub = int(P[I_NSUB])
    h = dt / n_sub
    half = 0.5 * P[I_BW]
    th_l = np.empty(n)
    om_l = np.empty(n)
    xl, vl = th_m[0], om_m[0]
    for k in range(n):
        th_l[k] = xl
        om_l[k] = vl
        if k == n - 1:
            break
        for i in range(n_sub):
            a = i / n_sub
            xm = th_m[k] + a * (th_m[k + 1] - th_m[k])
            vm = om_m[k] + a * (om_m[k + 1] - om_m[k])
            delta = xm - xl
            dz = delta - half if delta > half else (delta + half if delta < -half else 0.0)
            tau_c = P[I_CK] * dz
            if dz != 0.0:
                tau_c += P[I_CC] * (vm - vl)
            vl += h * (tau_c - P[I_GT] * math.sin(xl + P[I_GPH])) / P[I_JL]
            xl += h * vl
    return th_l, om_l


@njit(cache=True)
def _shoot_windows(
    P: FloatArray,
    u: FloatArray,
    dt: float,
    starts: NDArray[np.int64],
    horizon: int,
    settle: int,
    x0s: FloatArray,
    y: FloatArray,
    offsets: FloatArray,
    vrels: FloatArray,
) -> FloatArray:
    """Per window, start the load at each (offset, relative speed), keep the start that best
    predicts the first ``settle`` samples, return that start's errors. Shape (m, horizon)."""
    m = starts.shape[0]
    out = np.empty((m, horizon))
    x = np.empty(STATE_SIZE)
    for w in range(m):
        best_cost = np.inf
        best_o, best_v = 0.0, 0.0
        for o in offsets:
            for v in vrels:
                x[:] = x0s[w]
                x[2] = x[0] - o
                x[3] = x[1] + v
                cost = 0.0
                for i in range(1, settle + 1):
                    advance(x, P, u, starts[w] + i - 1, dt, 0.0)
                    d = y[w, i] - x[0]
                    cost += d * d
                if cost < best_cost:
                    best_cost, best_o, best_v = cost, o, v
        x[:] = x0s[w]
        x[2] = x[0] - best_o
        x[3] = x[1] + best_v
        out[w, 0] = y[w, 0] - x[0]
        for i in range(1, horizon):
            advance(x, P, u, starts[w] + i - 1, dt, 0.0)
            out[w, i] = y[w, i] - x[0]
    return out


def observe_load(
    model: AxisModel, theta_m_rad: FloatArray, omega_m_rad_s: FloatArray, dt_s: float
) -> tuple[FloatArray, FloatArray]:
    """Load angle and velocity (shape (n,) each) of a two-mass ``model`` driven by the motor."""
    P = pack_params(model, dt_s, quantize=False)
    if P[I_TWO] == 0.0:
        return theta_m_rad.copy(), omega_m_rad_s.copy()
    return _load_observer(
        P, np.ascontiguousarray(theta_m_rad), np.ascontiguousarray(omega_m_rad_s), float(dt_s)
    )


@dataclass(frozen=True, slots=True)
class KStepScore:
    """Errors of one model: ``window_sse`` per window (all horizons), ``end_error`` at the horizon."""

    window_sse: FloatArray
    end_error: FloatArray
    fit_percent: float

    @property
    def sse(self) -> float:
        return float(self.window_sse.sum())


@dataclass(frozen=True, slots=True)
class Comparison:
    """A candidate against the current model: relative error reduction and its t statistic."""

    improvement: float
    t_stat: float
    robust_improvement: float = 0.0


class KStepJudge:
    """Scores models by k-step prediction on windows of one measured run."""

    def __init__(
        self, meas: Measurement, sig: Signals, horizon_s: float | None = None, stride: int | None = None
    ) -> None:
        self.meas = meas
        self.dt = meas.dt_s
        self.k = max(2, int(round((horizon_s or DEFAULT_HORIZON_S) / self.dt)))
        self.stride = stride or self.k
        self.starts = np.arange(self.k, meas.n - self.k - 1, self.stride, dtype=np.int64)
        self.u = np.ascontiguousarray(meas.u_v, dtype=float)
        th = sig.theta_rad.copy()
        om = sig.omega_rad_s.copy()
        # The simulator's velocity state at sample k is ω(t_k − h/2) (leapfrog): start there.
        om -= 0.5 * self.dt * np.concatenate(([0.0], sig.alpha_rad_s2[:-1]))
        om[sig.stuck] = 0.0  # a stuck axis starts stuck (Karnopp), not creeping
        th[sig.stuck] = meas.theta_rad[sig.stuck]
        self.theta_s, self.omega_s = th, om
        idx = self.starts[:, None] + np.arange(self.k + 1)[None, :]
        self.y = meas.theta_rad[idx]
        y_end = self.y[:, -1]
        self.end_norm = float(np.linalg.norm(y_end - y_end.mean())) or 1.0
        self.group = (self.starts // max(self.k, self.stride * 4)).astype(np.int64)
        self.k_settle = self.k // 3  # samples a hidden-state start may use to settle
        # Squared error per sample that is only measurement noise (quantization step²/12).
        self.noise_floor = max(sig.encoder_step_rad, 1e-12) ** 2 / 12.0
        self.encoder_step_rad = max(sig.encoder_step_rad, 1e-12)

    def subset(self, keep: NDArray[np.bool_]) -> KStepJudge:
        """The same judge on the windows in ``keep`` only (a mask over :attr:`starts`)."""
        out = copy.copy(self)
        out.starts, out.y, out.group = self.starts[keep], self.y[keep], self.group[keep]
        y_end = out.y[:, -1]
        out.end_norm = float(np.linalg.norm(y_end - y_end.mean())) or 1.0
        return out

    def halves(self) -> NDArray[np.int64]:
        """0/1 per window: the half of the run (alternating 1 s blocks) it starts in."""
        return ((self.starts * self.dt) // 1.0).astype(np.int64) % 2

    def initial_states(self, model: AxisModel) -> FloatArray:
        x0 = np.empty((self.starts.size, STATE_SIZE))
        x0[:, 0] = self.theta_s[self.starts]
        x0[:, 1] = self.omega_s[self.starts]
        if model.has("backlash") or model.has("compliance"):
            th_l, om_l = observe_load(model, self.theta_s, self.omega_s, self.dt)
            x0[:, 2], x0[:, 3] = th_l[self.starts], om_l[self.starts]
        else:
            x0[:, 2], x0[:, 3] = x0[:, 0], x0[:, 1]
        return x0

    def errors(self, model: AxisModel) -> FloatArray:
        """Measured − predicted, shape (m, k + 1).

        With backlash the load's place in the dead band is not observable from a short past
        (a frictionless load coasts in the gap), so each window starts from the best of a few
        places in the band, chosen on the window's first third only (multiple shooting);
        :meth:`score` counts the errors after that third, for every model alike.
        """
        x0 = self.initial_states(model)
        if not model.has("backlash"):
            pred = predict_windows(model, self.u, self.dt, self.starts, self.k + 1, x0)
            return np.asarray(self.y - pred, dtype=float)
        half = 0.5 * model.params["backlash.width"]
        offsets = np.linspace(-half, half, BACKLASH_STARTS)
        speed = float(np.percentile(np.abs(self.omega_s), 90)) or 1.0
        vrels = speed * np.array([-0.1, 0.0, 0.1])
        P = pack_params(model, self.dt, quantize=False, rail_v=drive_rail_v(self.u))
        return _shoot_windows(
            P, self.u, self.dt, self.starts, self.k + 1, self.k_settle, x0, self.y, offsets, vrels
        )

    def score(self, model: AxisModel) -> KStepScore:
        e = self.errors(model)
        end = e[:, -1]
        fit = 100.0 * (1.0 - float(np.linalg.norm(end)) / self.end_norm)
        return KStepScore(np.sum(e[:, self.k_settle + 1 :] ** 2, axis=1), end, fit)

    def sliding(self) -> NDArray[np.bool_]:
        """Windows in which the axis slides one way throughout, from a horizon before the start
        to the end (no rest, no reversal), by at least two encoder counts per horizon.

        Friction's pre-sliding (the bristles of LuGre, the contact's elasticity) acts only at
        rest and for a short travel after a reversal; in these windows it is spent.
        """
        v_min = 2.0 * self.encoder_step_rad / (self.k * self.dt)
        idx = (self.starts - self.k)[:, None] + np.arange(2 * self.k + 1)[None, :]
        om = self.omega_s[np.clip(idx, 0, self.omega_s.size - 1)]
        return np.asarray(np.all(om > v_min, axis=1) | np.all(om < -v_min, axis=1))

    def gain_where(self, base: KStepScore, cand: KStepScore, mask: NDArray[np.bool_]) -> float:
        """Share of the base model's error removed over the windows in ``mask`` (0 when none)."""
        b = float(base.window_sse[mask].sum())
        return 1.0 - float(cand.window_sse[mask].sum()) / b if b > 0 else 0.0

    def half_gains(self, base: KStepScore, cand: KStepScore) -> tuple[float, float]:
        """Error reduction on each half of the run (alternating 1 s blocks)."""
        half = self.halves()
        out = []
        for h in (0, 1):
            b = float(base.window_sse[half == h].sum())
            out.append(1.0 - float(cand.window_sse[half == h].sum()) / b if b > 0 else 0.0)
        return out[0], out[1]

    def compare(self, base: KStepScore, cand: KStepScore) -> Comparison:
        """Paired comparison over blocks of windows (blocks ≥ 4 windows long).

        ``improvement`` is the share of the base model's squared error removed;
        ``robust_improvement`` the same without the ``TRIM_BLOCKS`` blocks that gained most (a
        real effect does not hinge on one or two lucky stretches); ``t_stat`` the paired t
        statistic of the block differences (block errors are heavy-tailed: a few fast steps
        dominate, so it is reported, not used as the gate).
        """
        b = np.bincount(self.group, weights=base.window_sse)
        c = np.bincount(self.group, weights=cand.window_sse)
        tot = float(b.sum())
        if tot <= 0:
            return Comparison(0.0, 0.0, 0.0)
        d = b - c
        improvement = float(d.sum() / tot)
        keep = np.argsort(d)[: max(1, d.size - TRIM_BLOCKS)]
        robust = float(d[keep].sum() / b[keep].sum()) if b[keep].sum() > 0 else 0.0
        sd = float(d.std(ddof=1)) if d.size > 1 else 0.0
        t = float(d.mean() / sd * math.sqrt(d.size)) if sd > 0 else 0.0
        return Comparison(improvement, t, robust)


@dataclass(frozen=True, slots=True)
class HeldOutSearch:
    """A grid search scored by k-step error, chosen on one half of the run, judged on the other.

    ``best`` is the grid point best on all windows; ``held_out_gain`` the mean over the two
    halves of the error reduction (vs the base model) on the half the choice was not made on.
    """

    best: AxisModel
    best_index: int
    held_out_gain: float
    gains: tuple[float, float]


def held_out_search(judge: KStepJudge, base: KStepScore, models: Sequence[AxisModel]) -> HeldOutSearch:
    """Score ``models`` (a grid over an effect's parameters) with a two-fold held-out choice."""
    half = judge.halves()
    sse = np.array([judge.score(m).window_sse for m in models])  # (g, m)
    base_half = np.array([base.window_sse[half == h].sum() for h in (0, 1)])
    by_half = np.stack([sse[:, half == h].sum(axis=1) for h in (0, 1)], axis=1)  # (g, 2)
    gains = []
    for h in (0, 1):
        pick = int(np.argmin(by_half[:, 1 - h]))
        gains.append(float(1.0 - by_half[pick, h] / base_half[h]) if base_half[h] > 0 else 0.0)
    best = int(np.argmin(sse.sum(axis=1)))
    return HeldOutSearch(models[best], best, float(np.mean(gains)), (gains[0], gains[1]))


def with_values(model: AxisModel, values: Mapping[str, float], add: str | None = None) -> AxisModel:
    """``model`` (plus effect ``add``) with ``values`` set, keeping every other value.

    (``AxisModel.with_effect`` would reset an existing asymmetry to symmetric.)
    """
    effects = (*model.effects, add) if add and not model.has(add) else model.effects
    keep = dict(model.params)
    keep.update(
        {k: v for k, v in values.items() if k.split(".")[0] in (*effects, "inertia", "viscous", "coulomb")}
    )
    return AxisModel.create(model.gain_nm_per_v, {}, effects, keep)


def refine(
    judge: KStepJudge,
    model: AxisModel,
    names: Sequence[str] | None = None,
    max_evals: int = 40,
    cancel: Callable[[], bool] | None = None,
) -> tuple[AxisModel, dict[str, float]]:
    """Least-squares refit of ``names`` (default: the model's free parameters) by k-step error.

    Starts from ``model``'s values (the screening's), stays within each parameter's bounds.
    Returns the refitted model and the standard errors of the fitted parameters.
    """
    keys = list(names or model.free_param_names())
    x0 = np.array([model.params[k] for k in keys])
    lo = np.array([get_param(k).lower for k in keys])
    hi = np.array([get_param(k).upper for k in keys])
    scale = np.maximum(np.abs(x0), 1e-3 * (hi - lo).clip(max=1.0))
    for i, k in enumerate(keys):
        if k.endswith(".phase"):
            lo[i], hi[i], scale[i] = -np.inf, np.inf, 0.3
    z0 = np.clip(x0, lo + 1e-12 * scale, hi - 1e-12 * scale) / scale

    def wrap(values: FloatArray) -> dict[str, float]:
        out = {}
        for k, v in zip(keys, values, strict=True):
            if k.endswith(".phase"):
                v = (v + math.pi) % (2 * math.pi) - math.pi
            out[k] = float(v)
        return out

    def resid(z: FloatArray) -> FloatArray:
        if cancel is not None and cancel():
            raise JobCancelled("diagnosis cancelled while refitting a candidate")
        m = with_values(model, wrap(z * scale))
        return judge.errors(m)[:, judge.k_settle + 1 :: 3].ravel()

    # Robust loss: a window whose error comes from something no model here has (a disturbance
    # that starts the axis early from rest) must not pull the parameters; errors beyond a few
    # times the typical one count linearly, not squared.
    r0 = resid(z0)
    f_scale = max(3.0 * 1.4826 * float(np.median(np.abs(r0))), math.sqrt(judge.noise_floor))
    sol = optimize.least_squares(
        resid,
        z0,
        bounds=(lo / scale, hi / scale),
        x_scale=1.0,
        max_nfev=max_evals,
        diff_step=1e-3,
        method="trf",
        loss="soft_l1",
        f_scale=f_scale,
    )
    fitted = with_values(model, wrap(sol.x * scale))
    # Standard errors: Gauss–Newton covariance, inflated by the residual's correlation length
    # (errors within a prediction window are far from independent).
    r = sol.fun
    m, p = sol.jac.shape
    per_window = max(1, m // judge.starts.size)
    sigma2 = float(r @ r) / max(1, m - p)
    try:
        cov = np.linalg.pinv(sol.jac.T @ sol.jac) * sigma2 * per_window
        se = np.sqrt(np.clip(np.diag(cov), 0, None)) * scale
    except np.linalg.LinAlgError:
        se = np.full(p, math.inf)
    return fitted, {k: float(v) for k, v in zip(keys, se, strict=True)}


__all__ = [
    "DEFAULT_HORIZON_S",
    "Comparison",
    "HeldOutSearch",
    "KStepJudge",
    "KStepScore",
    "held_out_search",
    "observe_load",
    "refine",
]
