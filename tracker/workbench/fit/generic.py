"""Generic effects in a regression: the columns of a torque τ(θ; p) that is not built in.

An effect without code of its own (see :mod:`tracker.plant.effects`) enters the torque balance
through the derivatives of its torque with respect to its parameters, taken numerically::

    τ(θ; p) = τ(θ; p₀) + Σᵢ (pᵢ − p₀ᵢ)·∂τ/∂pᵢ(θ; p₀)  =  r(θ) + Σᵢ pᵢ·gᵢ(θ)

so the regression's coefficient of the column gᵢ is pᵢ itself and r = τ(p₀) − Σ p₀ᵢ gᵢ moves to
the other side. This is exact for a parameter the torque is linear in (amplitude, slope,
offset): those always get a column. A parameter it is not linear in is held at a value (searched
on the effect's grid, ``Effect.search``, when it declares one) and then polished by Gauss–Newton
steps, each a regression with columns for every parameter linearized at the current estimate.
Parameters with ``fit=False`` and no grid keep their values.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from tracker.plant.effects import Effect, get_effect

if TYPE_CHECKING:
    from tracker.workbench.diagnose.screening import Structure, TorqueDesign
    from tracker.workbench.measurements.idim import Regression

FloatArray = NDArray[np.float64]

# Relative tolerance of the numerical test that a torque is linear in a parameter.
LINEAR_TOL = 1e-7
GAUSS_NEWTON_STEPS = 6
_PROBE = np.linspace(-math.pi, math.pi, 33)


def _step(effect: Effect, name: str, value: float) -> float:
    """A difference step for parameter ``name`` (short name) at ``value``."""
    prm = effect.param(name)
    span = prm.upper - prm.lower
    scale = max(abs(value), abs(prm.default), 1e-3 * min(span, 1e3) if math.isfinite(span) else 1.0, 1e-9)
    return 1e-4 * scale


def defaults(effect: Effect) -> dict[str, float]:
    """Every parameter of ``effect`` at its default, by full name."""
    return {f"{effect.name}.{p.name}": p.default for p in effect.params}


_LINEAR: dict[tuple[int, str], tuple[Effect, bool]] = {}


def _is_linear(effect: Effect, name: str) -> bool:
    """Whether τ is affine in parameter ``name`` (probed at three values inside its bounds)."""
    key = (id(effect), name)
    if key not in _LINEAR or _LINEAR[key][0] is not effect:
        _LINEAR[key] = (effect, _probe_linear(effect, name))
    return _LINEAR[key][1]


def _probe_linear(effect: Effect, name: str) -> bool:
    prm = effect.param(name)
    reach = 1.0 + abs(prm.default)
    lo = max(prm.lower, prm.default - reach)
    hi = min(prm.upper, prm.default + reach)
    values = (lo, 0.5 * (lo + hi), hi)
    p = defaults(effect)
    full = f"{effect.name}.{name}"
    taus = [torque_at_rest(effect, {**p, full: v}, _PROBE) for v in values]
    predicted = taus[0] + (taus[2] - taus[0]) * (values[1] - values[0]) / (values[2] - values[0])
    scale = max(float(np.max(np.abs(taus[0]))), float(np.max(np.abs(taus[2]))), 1e-300)
    return bool(np.max(np.abs(taus[1] - predicted)) <= LINEAR_TOL * scale)


def fitted_params(effect: Effect) -> tuple[str, ...]:
    """Full names of the parameters the data determine: fitted (``Param.fit``) or searched."""
    return tuple(f"{effect.name}.{p.name}" for p in effect.params if p.fit or p.name in effect.search)


def linear_params(effect: Effect) -> tuple[str, ...]:
    """The fitted parameters the torque is linear in (not searched): a regression column each."""
    return tuple(
        n
        for n in fitted_params(effect)
        if n.partition(".")[2] not in effect.search and _is_linear(effect, n.partition(".")[2])
    )


def nonlinear_params(effect: Effect) -> tuple[str, ...]:
    """The fitted parameters held at a value in a regression (searched, or not linear)."""
    linear = linear_params(effect)
    return tuple(n for n in fitted_params(effect) if n not in linear)


def held_params(effect: Effect) -> tuple[str, ...]:
    """Full names of the parameters a regression holds: nonlinear and fixed ones. A
    :class:`~tracker.workbench.diagnose.screening.Structure` carries their values."""
    linear = linear_params(effect)
    return tuple(n for n in effect.full_names() if n not in linear)


def param_count(name: str) -> int:
    """How many parameters the data must pin down for effect ``name`` (fitted and searched)."""
    return len(fitted_params(get_effect(name))) or 1


def point(effect: Effect, values: Mapping[str, float]) -> dict[str, float]:
    """The effect's parameters (full names): defaults, replaced by those in ``values``."""
    return {k: float(values.get(k, v)) for k, v in defaults(effect).items()}


def torque_at_rest(effect: Effect, params: Mapping[str, float], theta_rad: FloatArray) -> FloatArray:
    """τ(θ) at rest, shape of ``theta_rad``."""
    th = np.asarray(theta_rad, dtype=float)
    return np.asarray(effect.torque_nm(params, th, np.zeros_like(th)), dtype=float)


def derivative(
    effect: Effect, params: Mapping[str, float], full_name: str, theta_rad: FloatArray
) -> FloatArray:
    """∂τ/∂p at ``params`` (central difference; one-sided at a bound), shape of ``theta_rad``."""
    name = full_name.partition(".")[2]
    prm = effect.param(name)
    v = float(params[full_name])
    h = _step(effect, name, v)
    lo, hi = max(v - h, prm.lower), min(v + h, prm.upper)
    if hi <= lo:
        return np.zeros_like(np.asarray(theta_rad, dtype=float))
    t_hi = torque_at_rest(effect, {**params, full_name: hi}, theta_rad)
    t_lo = torque_at_rest(effect, {**params, full_name: lo}, theta_rad)
    return (t_hi - t_lo) / (hi - lo)


def columns(
    effect: Effect, params: Mapping[str, float], theta_rad: FloatArray, names: Sequence[str]
) -> tuple[list[tuple[str, FloatArray]], FloatArray]:
    """The regression columns gᵢ = ∂τ/∂pᵢ for the parameters ``names`` (full names) and the rest
    r = τ − Σ pᵢ gᵢ of ``effect`` at ``params`` (which must hold every parameter of the effect)."""
    cols = [(n, derivative(effect, params, n, theta_rad)) for n in names]
    rest = torque_at_rest(effect, params, theta_rad)
    for n, g in cols:
        rest = rest - params[n] * g
    return cols, rest


def _own(reg: Regression, effect: str) -> dict[str, float]:
    """The regression's coefficients of ``effect``'s parameters (full names)."""
    return {n: float(c) for n, c in zip(reg.names, reg.coef, strict=True) if n.startswith(f"{effect}.")}


def _clip(effect: Effect, full_name: str, value: float) -> float:
    prm = effect.param(full_name.partition(".")[2])
    return float(min(max(value, prm.lower), prm.upper))


def gauss_newton(
    design: TorqueDesign, structure: Structure, reg: Regression, effect: str, n_eff: float
) -> tuple[Structure, Regression]:
    """Refine the nonlinear parameters of generic ``effect`` held in ``structure`` (whose
    regression is ``reg``): each step regresses on columns for every parameter, linearized at the
    current estimate, and is kept while the error of the held regression falls."""
    eff = get_effect(effect)
    nonlinear = nonlinear_params(eff)
    for _ in range(GAUSS_NEWTON_STEPS if nonlinear else 0):
        at = {**structure.settings, **_own(reg, effect)}
        moved = _own(design.fit(replace(structure, settings=at, linearized=effect), n_eff, cv=False), effect)
        settings = {**structure.settings, **{n: _clip(eff, n, moved[n]) for n in nonlinear}}
        nxt = replace(structure, settings=settings)
        reg_next = design.fit(nxt, n_eff, cv=False)
        if not reg_next.sse < reg.sse:
            break
        structure, reg = nxt, reg_next
    return structure, reg


def held_stderr(
    design: TorqueDesign, structure: Structure, reg: Regression, effect: str, n_eff: float
) -> dict[str, float]:
    """Standard errors of the nonlinear parameters of ``effect`` held in ``structure``: from the
    regression linearized at the final values (the Gauss–Newton covariance)."""
    nonlinear = nonlinear_params(get_effect(effect))
    if not nonlinear:
        return {}
    at = {**structure.settings, **_own(reg, effect)}
    lin = design.fit(replace(structure, settings=at, linearized=effect), n_eff, cv=False)
    return {n: float(math.sqrt(max(lin.cov[i, i], 0.0))) for i, n in enumerate(lin.names) if n in nonlinear}


__all__ = [
    "columns",
    "defaults",
    "derivative",
    "fitted_params",
    "gauss_newton",
    "held_params",
    "held_stderr",
    "linear_params",
    "nonlinear_params",
    "param_count",
    "point",
    "torque_at_rest",
]
