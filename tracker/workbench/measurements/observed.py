"""k-step window predictions of a model from observed states, in one compiled pass.

The fitter and the searches judge a two-mass model (``backlash``, ``compliance``) by windows of
k-step predictions started from the smoother's motor state and the model-based observer's
load state (:func:`~tracker.workbench.measurements.states.with_load_observer`). Done in steps,
that is one observer pass writing an (n, 4) array, a copy of every estimate, and a second
compiled pass over the windows, for every candidate model. Here the observer runs once along
the log and each window is predicted when the observer reaches its start: the same numbers
(bit for bit), without the arrays in between, and the observer stops at the last window.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.errors import DataError
from tracker.plant.effects.saturation import drive_rail_v
from tracker.plant.model import AxisModel
from tracker.plant.simulate import pack_params, predict_windows, step_state
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.states import OBSERVER_BANDWIDTH_HZ, StateEstimate

FloatArray = NDArray[np.float64]


# Without numba's reference counting (its ``_nrt`` option): the arrays are the caller's (``out``
# too), and counting the ones handed to the inlined plant step at every sample took a third of
# the time.
_F = TypeVar("_F", bound=Callable[..., Any])
_NO_REFCOUNT: dict[str, Any] = {"_nrt": False}
_njit_no_refcount = cast(Callable[[_F], _F], njit(cache=True, **_NO_REFCOUNT))


@_njit_no_refcount
def _observed_windows(
    P_obs: FloatArray,
    P_win: FloatArray,
    u: FloatArray,
    y: FloatArray,
    dt: float,
    l_pos: float,
    l_vel: float,
    starts: NDArray[np.int64],
    horizon: int,
    motor0: FloatArray,
    load_shift: FloatArray,
    abandon_sse: float,
    out: FloatArray,
) -> int:
    """Observer along ``y`` (as :func:`states._model_observer`) and, at each start, a window
    from [motor0[w, 0], motor0[w, 1], θl, (ωl + load_shift[w, 0]) − load_shift[w, 1]].

    Writes the predictions into ``out`` (shape (m, horizon)) and returns the windows done: when
    the summed squared error of the windows' steps 1..horizon−1 against ``y`` passes
    ``abandon_sse``, it stops there.
    """
    m: int = starts.shape[0]
    n = y.shape[0]
    sse = 0.0
    # The states live in scalars (registers): see step_state.
    x0, x1, x2, x3 = y[0], 0.0, y[0], 0.0
    k = 0
    for w in range(m):
        s = starts[w]
        while k < s:
            innov = y[k] - x0
            x0 += l_pos * innov
            x1 += l_vel * innov
            x0, x1, x2, x3 = step_state(x0, x1, x2, x3, P_obs, u, k, dt, 0.0)
            k += 1
        # The observer's correction at sample s touches only the motor side: x2, x3 are its
        # load estimate at s.
        w0 = motor0[w, 0]
        w1 = motor0[w, 1]
        w2 = x2
        w3 = (x3 + load_shift[w, 0]) - load_shift[w, 1]
        for i in range(horizon):
            out[w, i] = w0
            if i > 0 and s + i < n:
                e = y[s + i] - w0
                sse += e * e
            w0, w1, w2, w3 = step_state(w0, w1, w2, w3, P_win, u, s + i, dt, 0.0)
        if sse > abandon_sse:
            return w + 1
    return m


def predict_observed(
    model: AxisModel,
    meas: Measurement,
    est: StateEstimate,
    starts: NDArray[np.int64],
    horizon: int,
) -> FloatArray:
    """Windows of ``horizon`` samples of ``model``'s prediction of ``meas``, window w from sample
    ``starts[w]`` (non-decreasing), motor angle unquantized. Returns shape (m, horizon).

    The same as ``predict_windows(model, meas.u_v, dt, starts, horizon,
    with_load_observer(est, model, meas).initial_states(starts))``: the load side of a
    two-mass model comes from the model's observer, a rigid model's from the motor side.
    """
    return _predict(model, meas, est, starts, horizon, math.inf)[0]


def observed_cost(
    model: AxisModel,
    meas: Measurement,
    est: StateEstimate,
    starts: NDArray[np.int64],
    horizon: int,
    abandon_above: float = math.inf,
) -> float:
    """Mean squared error (rad²) of steps 1..horizon−1 of :func:`predict_observed`'s windows.

    A grid search only needs the best candidate's cost: once a candidate's summed error shows
    its mean must exceed ``abandon_above`` (the best so far), the pass stops and the cost is
    reported as infinite. Costs that are returned are computed exactly as without the bound.
    """
    s = np.ascontiguousarray(starts, dtype=np.int64)
    y = meas.theta_rad[s[:, None] + np.arange(1, horizon)[None, :]]
    # A little above the bound: the running sum and NumPy's mean round differently.
    sse_bound = abandon_above * y.size * (1.0 + 1e-9)
    pred, done = _predict(model, meas, est, s, horizon, sse_bound)
    if done < s.size:
        return math.inf
    return float(np.mean((y - pred[:, 1:]) ** 2))


def _predict(
    model: AxisModel,
    meas: Measurement,
    est: StateEstimate,
    starts: NDArray[np.int64],
    horizon: int,
    abandon_sse: float,
) -> tuple[FloatArray, int]:
    s = np.ascontiguousarray(starts, dtype=np.int64)
    if s.size and (s[0] < 0 or s[-1] >= meas.n or np.any(np.diff(s) < 0)):
        raise DataError(f"window starts must be non-decreasing sample indices below {meas.n}")
    dt = meas.dt_s
    motor = est.initial_states(s)
    if not (model.has("backlash") or model.has("compliance")):
        motor[:, 2] = motor[:, 0]
        motor[:, 3] = motor[:, 1]
        return predict_windows(model, meas.u_v, dt, s, horizon, motor), s.size
    u = np.ascontiguousarray(meas.u_v, dtype=float)
    if u.size and not np.all(np.isfinite(u)):
        bad = int(np.flatnonzero(~np.isfinite(u))[0])
        raise DataError(f"command sample {bad} is {u[bad]!r}")
    y = np.ascontiguousarray(meas.theta_rad, dtype=float)
    p = math.exp(-2.0 * math.pi * OBSERVER_BANDWIDTH_HZ * dt)
    half_dt = 0.5 * dt
    shift = np.empty((s.size, 2))
    shift[:, 0] = half_dt * est.alpha_rad_s2[s]
    shift[:, 1] = 0.5 * est.dt_s * est.alpha_rad_s2[np.maximum(s - 1, 0)]
    span = (float(motor[:, 0].min()), float(motor[:, 0].max())) if s.size else (0.0, 0.0)
    out = np.empty((s.size, int(horizon)))
    rail = drive_rail_v(u)
    done = _observed_windows(
        pack_params(model, dt, quantize=False, rail_v=rail),
        pack_params(model, dt, quantize=False, range_rad=span, rail_v=rail),
        u,
        y,
        dt,
        1.0 - p * p,
        (1.0 - p) ** 2 / dt,
        s,
        int(horizon),
        np.ascontiguousarray(motor[:, :2]),
        shift,
        float(abandon_sse),
        out,
    )
    return out, int(done)


__all__ = ["observed_cost", "predict_observed"]
