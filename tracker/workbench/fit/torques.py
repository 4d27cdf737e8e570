"""Model torques along estimated states: the residual torque and the linear least-squares start.

Given θ, ω, α estimated at every sample, the equation of motion
``J α = K·u_eff − b ω − Fc sign ω − offset − T_g sin(θ+φ) − A sin(nθ+ψ) − …`` is linear in
J, b, Fc, the asymmetries, the Stribeck break-away torque, the offset and the (cos, sin)
components of gravity and ripple. Least squares on it (moving samples only: at rest friction is
whatever holds the axis) gives the fitter its starting values from the data itself, whatever
the units of the axis, and reproduces the published EMPS identification method. The residual
torque is what a missing torque effect looks like ("residual torque follows sin θ").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import lsq_linear
from scipy.signal import butter, sosfiltfilt

from tracker.errors import DataError
from tracker.plant.effects import CATALOGUE, is_generic
from tracker.plant.effects.saturation import clip_level_v, drive_rail_v
from tracker.plant.model import AxisModel
from tracker.workbench.fit import generic
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.states import StateEstimate

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

# A sample counts as moving above this fraction of the 95th-percentile speed.
MOVING_FRACTION = 0.03


def replace_params(model: AxisModel, updates: Mapping[str, float]) -> AxisModel:
    """``model`` with some parameter values replaced, every other value kept.

    ``AxisModel.with_params`` rebuilds through ``create``, which resets an asymmetry's
    negative-direction value to its positive twin unless it is among the updates; the fitter
    must never lose a fixed or fitted asymmetry that way.
    """
    return AxisModel.create(model.gain_nm_per_v, {}, model.effects, {**model.params, **updates})


def effective_command_v(model: AxisModel, u_v: FloatArray, dt_s: float) -> FloatArray:
    """The command the motor gets: delayed by ``delay.seconds`` (linear interpolation), clipped
    at the saturation's limit (never below what ``u_v`` asks for without one)."""
    u = np.asarray(u_v, dtype=float)
    lim = clip_level_v(model.params, drive_rail_v(u))
    d = model.params.get("delay.seconds", 0.0)
    if d > 0.0:
        idx = np.arange(u.size) - d / dt_s
        u = np.interp(idx, np.arange(u.size), u)
    clipped: FloatArray = np.clip(u, -lim, lim)
    return clipped


def model_torque_nm(model: AxisModel, theta_rad: FloatArray, omega_rad_s: FloatArray) -> FloatArray:
    """Sum of the resisting torques of the base and torque-type effects, shape (n,)."""
    total = np.zeros_like(np.asarray(omega_rad_s, dtype=float))
    for name in ("viscous", "coulomb", *model.effects):
        eff = CATALOGUE[name]
        if eff.kind in ("base", "torque"):
            total = total + eff.torque_nm(model.params, theta_rad, omega_rad_s)
    return total


def residual_torque_nm(meas: Measurement, est: StateEstimate, model: AxisModel) -> FloatArray:
    """``K·u_eff − J α − Σ τ(θ, ω)``: the torque the model leaves unexplained, shape (n,).

    Rigid-body view (total J on the motor states), also for two-mass models.
    """
    u = effective_command_v(model, meas.u_v, meas.dt_s)
    return (
        model.gain_nm_per_v * u
        - model.params["inertia.J"] * est.alpha_rad_s2
        - model_torque_nm(model, est.theta_rad, est.omega_rad_s)
    )


def moving_mask(omega_rad_s: FloatArray) -> BoolArray:
    """Samples moving clearly (|ω| above 3 % of the 95th-percentile speed)."""
    w = np.abs(omega_rad_s)
    scale = float(np.percentile(w, 95))
    return w > MOVING_FRACTION * scale if scale > 0 else np.zeros(w.size, dtype=bool)


@dataclass(frozen=True, slots=True)
class InverseDynamicsFit:
    """Result of the linear inverse-dynamics least squares.

    ``params`` holds every parameter of the model (fitted ones replaced); ``relative_error_percent``
    is ‖τ_res‖/‖K u‖ on the samples used (the EMPS paper's "relative force error").
    """

    params: dict[str, float]
    relative_error_percent: float
    samples: int


def _columns(
    model: AxisModel, th: FloatArray, om: FloatArray, al: FloatArray, free: Sequence[str]
) -> tuple[list[str], list[FloatArray]]:
    """Regressor columns (coefficients of the resisting torque) for the linear free parameters."""
    p = model.params
    pos, neg = om > 0, om < 0
    sgn = np.sign(om)
    names: list[str] = []
    cols: list[FloatArray] = []

    def add(name: str, col: FloatArray) -> None:
        names.append(name)
        cols.append(col)

    stribeck = np.zeros_like(om)
    if model.has("stiction"):
        stribeck = np.exp(-((om / p["stiction.velocity"]) ** 2))
    if "inertia.J" in free:
        add("inertia.J", al)
    asym_v = model.has("viscous_asymmetry")
    if "viscous.b" in free:
        add("viscous.b", om * pos if asym_v else om)
    if asym_v and "viscous_asymmetry.negative" in free:
        add("viscous_asymmetry.negative", om * neg)
    asym_c = model.has("coulomb_asymmetry")
    if "coulomb.torque" in free:
        add("coulomb.torque", (pos * 1.0 if asym_c else sgn) * (1.0 - stribeck))
    if asym_c and "coulomb_asymmetry.negative" in free:
        add("coulomb_asymmetry.negative", -(neg * 1.0) * (1.0 - stribeck))
    if model.has("stiction") and "stiction.static_torque" in free:
        add("stiction.static_torque", stribeck * sgn)
    if model.has("offset") and "offset.torque" in free:
        add("offset.torque", np.ones_like(om))
    if model.has("gravity") and "gravity.torque" in free:
        add("gravity.cos", np.sin(th))  # T cos φ · sin θ
        add("gravity.sin", np.cos(th))  # T sin φ · cos θ
    if model.has("ripple") and "ripple.amplitude" in free:
        n = p["ripple.cycles_per_rev"]
        add("ripple.cos", np.sin(n * th))
        add("ripple.sin", np.cos(n * th))
    for e in model.effects:
        if is_generic(e):
            eff = CATALOGUE[e]
            at = generic.point(eff, p)
            for name in linear_generic_params(model, free):
                if name.startswith(f"{e}."):
                    add(name, generic.derivative(eff, at, name, th))
    return names, cols


def linear_generic_params(model: AxisModel, free: Sequence[str]) -> tuple[str, ...]:
    """The free parameters of ``model``'s generic effects that its torque is linear in (the
    inverse dynamics fits these; searched and nonlinear ones keep their values)."""
    out: list[str] = []
    for e in model.effects:
        if is_generic(e):
            out += [n for n in generic.linear_params(CATALOGUE[e]) if n in free]
    return tuple(out)


def _bounds(name: str) -> tuple[float, float]:
    if name.endswith((".cos", ".sin")):
        return -np.inf, np.inf
    eff, _, par = name.partition(".")
    for prm in CATALOGUE[eff].params:
        if prm.name == par:
            return prm.lower, prm.upper
    raise KeyError(name)


def _zero_linear(model: AxisModel, free: Sequence[str]) -> AxisModel:
    """``model`` with the torque of its linear free parameters removed (the rest stays).

    The asymmetry and Stribeck torques are written relative to their positive twins (see
    ``tracker.plant.effects``), so a fixed negative-side value keeps its full torque when the
    twin is zeroed.
    """
    linear = (
        "viscous.b",
        "coulomb.torque",
        "offset.torque",
        "gravity.torque",
        "ripple.amplitude",
        "viscous_asymmetry.negative",
        "coulomb_asymmetry.negative",
        "stiction.static_torque",
    )
    return replace_params(model, {k: 0.0 for k in linear if k in free and k in model.params})


def _fold_components(params: dict[str, float], effect: str) -> None:
    """Turn fitted (T cos φ, T sin φ) components into amplitude and phase."""
    c = params.pop(f"{effect}.cos", None)
    s = params.pop(f"{effect}.sin", None)
    if c is None or s is None:
        return
    amp_name = "gravity.torque" if effect == "gravity" else "ripple.amplitude"
    params[amp_name] = float(math.hypot(c, s))
    params[f"{effect}.phase"] = float(math.atan2(s, c))


def _lowpass(cutoff_hz: float, dt_s: float) -> Callable[[FloatArray], FloatArray]:
    """A zero-phase 4th-order Butterworth low-pass at ``cutoff_hz``."""
    wn = min(0.99, 2.0 * cutoff_hz * dt_s)
    sos = butter(4, wn, output="sos")
    return lambda x: sosfiltfilt(sos, x)


def fit_inverse_dynamics(
    meas: Measurement,
    est: StateEstimate,
    model: AxisModel,
    free: Sequence[str] | None = None,
    mask: BoolArray | None = None,
    cutoff_hz: float | None = None,
) -> InverseDynamicsFit:
    """Least squares of ``K u_eff = J α + Σ τ(θ, ω)`` for the linear parameters in ``free``.

    Parameters not in ``free`` (and the nonlinear ones: delay, saturation, Stribeck velocity,
    ripple cycles, two-mass parameters) stay at the model's values; their torque moves to the
    left-hand side. Bounds come from the catalogue. ``mask`` selects samples (default: moving).
    ``cutoff_hz`` low-passes both sides of the equation with the same zero-phase filter first
    (the equation is linear in the parameters, so the filter cancels out of it): below a belt
    resonance the axis moves as one rigid body, which is what this regression assumes.
    """
    free_set = list(model.free_param_names() if free is None else free)
    th, om, al = est.theta_rad, est.omega_rad_s, est.alpha_rad_s2
    sel = moving_mask(om) if mask is None else mask
    if int(sel.sum()) < 20:
        raise DataError(
            f"{meas.source or '<data>'}: the axis hardly moves; cannot identify friction or inertia"
        )
    names, cols = _columns(model, th, om, al, free_set)
    lhs = model.gain_nm_per_v * effective_command_v(model, meas.u_v, meas.dt_s)
    rhs = lhs - model_torque_nm(_zero_linear(model, free_set), th, om)
    for name, col in zip(names, cols, strict=True):
        if is_generic(name.partition(".")[0]):  # its torque stayed in; take its fitted part out
            rhs = rhs + model.params[name] * col
    if "inertia.J" not in free_set:
        rhs = rhs - model.params["inertia.J"] * al
    if cutoff_hz is not None:
        lowpass = _lowpass(cutoff_hz, meas.dt_s)
        cols = [lowpass(c) for c in cols]
        lhs, rhs = lowpass(lhs), lowpass(rhs)
    cols = [c[sel] for c in cols]
    lhs, rhs = lhs[sel], rhs[sel]
    params = dict(model.params)
    res = rhs
    if names:
        A = np.column_stack(cols)
        scale = np.maximum(np.sqrt(np.mean(A * A, axis=0)), 1e-300)
        lo_hi = np.array([_bounds(n) for n in names]).T
        # Bounded LS on the QR-reduced p×p problem: same solution, no n-long iterations.
        q, r = np.linalg.qr(A / scale)
        sol = lsq_linear(r, q.T @ rhs, bounds=(lo_hi[0] * scale, lo_hi[1] * scale), method="bvls")
        coef = sol.x / scale
        for name, c in zip(names, coef, strict=True):
            params[name] = float(c)
        _fold_components(params, "gravity")
        _fold_components(params, "ripple")
        res = rhs - A @ coef
    rel = 100.0 * float(np.linalg.norm(res) / max(float(np.linalg.norm(lhs)), 1e-300))
    return InverseDynamicsFit(params, rel, int(sel.sum()))


__all__ = [
    "InverseDynamicsFit",
    "replace_params",
    "effective_command_v",
    "fit_inverse_dynamics",
    "linear_generic_params",
    "model_torque_nm",
    "moving_mask",
    "residual_torque_nm",
]
