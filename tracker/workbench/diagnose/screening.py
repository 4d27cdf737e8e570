"""Screening: how much of the residual torque each missing effect explains (inverse dynamics).

For the current model's structure and for the structure with one more effect, the torque
``K·u`` is regressed on the filtered columns of every term (see :mod:`tracker.workbench.measurements.idim`).
Effects with a nonlinear parameter are searched over it: ripple cycles by a periodogram of
the residual torque against θ, Stribeck velocity, delay, clip level, backlash width and belt
frequency/damping on grids. Hidden load states (backlash, compliance) are reconstructed from
the encoder trajectory: the load is driven through the dead band (a coasting load caught by
the motor) or through the belt (a second-order filter), and the total momentum balance
``K·u = J_m·α_m + J_l·α_l + friction`` stays linear in both inertias. Effects that are not built
in enter through the derivatives of their torque (:mod:`tracker.workbench.fit.generic`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import signal

from tracker.errors import DataError
from tracker.plant.effects import get_effect, get_param, is_generic
from tracker.plant.effects.saturation import clip_level_v, drive_rail_v
from tracker.plant.model import AxisModel
from tracker.workbench.fit import generic
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.idim import (
    Regression,
    Signals,
    circular_fit,
    delayed,
    effective_samples,
    improvement_p_value,
    prepare_signals,
    regress,
)

FloatArray = NDArray[np.float64]
Column = tuple[str, FloatArray]

# Nonlinear settings a structure carries (what the linear regression cannot fit).
NONLINEAR = {
    "ripple": "ripple.cycles_per_rev",
    "stiction": "stiction.velocity",
    "delay": "delay.seconds",
    "saturation": "saturation.limit",
    "backlash": "backlash.width",
}


@dataclass(frozen=True, slots=True)
class Structure:
    """A model structure for regression: its effects and their nonlinear settings.

    ``linearized`` names a generic effect whose every fitted parameter gets a column, linearized
    at the values in ``settings`` (a Gauss–Newton step); otherwise only its linear ones do.
    """

    effects: tuple[str, ...]
    settings: Mapping[str, float] = field(default_factory=dict)
    linearized: str | None = None

    @classmethod
    def of(cls, model: AxisModel) -> Structure:
        s = {
            k: model.params[k]
            for k in (*NONLINEAR.values(), "compliance.frequency", "compliance.damping")
            if k in model.params
        }
        for e in model.effects:
            if is_generic(e):
                s.update({k: model.params[k] for k in generic.held_params(get_effect(e))})
        return cls(tuple(model.effects), s)

    def plus(self, effect: str, **settings: float) -> Structure:
        return Structure((*self.effects, effect), {**self.settings, **settings})


@dataclass(frozen=True, slots=True)
class Screen:
    """One structure's regression and what it implies for the model's parameters."""

    effect: str
    structure: Structure
    regression: Regression
    params: Mapping[str, float]
    stderr: Mapping[str, float]
    gain_cv: float
    p_value: float
    folds_improve: bool
    detail: Mapping[str, float]


@njit(cache=True)
def _play(theta_m: FloatArray, dt: float, half: float, fall_rad_s2: float, phase_rad: float) -> FloatArray:
    """Load angle behind a dead band: between the flanks it moves under the torques acting on
    the load alone, its gravity ``−fall·sin(θ_l + phase)`` (``fall`` = T_g / J_l, rad/s²; zero
    without gravity: it coasts), until the motor catches it. Shape (n,)."""
    n = theta_m.shape[0]
    out = np.empty(n)
    xl = theta_m[0]
    vl = 0.0
    for k in range(n):
        # Semi-implicit Euler in the gap (the velocity first): with no gravity the load coasts.
        v_free = vl - fall_rad_s2 * math.sin(xl + phase_rad) * dt if k > 0 else 0.0
        pred = xl + v_free * dt
        d = theta_m[k] - pred
        if d > half:
            new = theta_m[k] - half
        elif d < -half:
            new = theta_m[k] + half
        else:
            new = pred
        vl = (new - xl) / dt if k > 0 else 0.0
        xl = new
        out[k] = xl
    return out


def load_fall(model: AxisModel) -> tuple[float, float]:
    """What pulls a load that is off both flanks of a dead band: the model's gravity (it acts
    on the load) over the load's inertia, T_g / J_l (rad/s²), and its phase; (0, 0) without.

    A load with an unbalance does not coast through the gap: it falls onto the flank gravity
    presses it against, and leaves it only when the motor pulls it away faster than it falls
    (the contact then changes with the sign of the torque the load needs, J_l·α_l + gravity,
    not with the motor's acceleration).
    """
    if not model.has("gravity"):
        return (0.0, 0.0)
    return gravity_fall(model.params, model.params["inertia.motor_fraction"])


def gravity_fall(params: Mapping[str, float], motor_fraction: float) -> tuple[float, float]:
    """The fall T_g / J_l (rad/s²) and phase of :func:`load_fall` from gravity's and the
    inertia's values in ``params``, the load's inertia being ``1 − motor_fraction`` of the
    axis's; (0, 0) when the load has no inertia."""
    j_load = params["inertia.J"] * (1.0 - motor_fraction)
    if j_load <= 0.0:
        return (0.0, 0.0)
    return (float(params["gravity.torque"] / j_load), float(params["gravity.phase"]))


class TorqueDesign:
    """Builds filtered regression columns and torques for any structure on one prepared run."""

    def __init__(
        self,
        sig: Signals,
        gain_nm_per_v: float,
        motor_fraction: float,
        load_fall: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        self.sig = sig
        self.gain = gain_nm_per_v
        self.frac = motor_fraction
        # The load's own gravity behind a dead band (fall T_g/J_l in rad/s², phase): see
        # :func:`load_fall` and :func:`_play`.
        self.load_fall = load_fall
        self.sgn = np.sign(sig.omega_rad_s)
        self.rail_v = drive_rail_v(sig.u_v)
        self._cache: dict[tuple[object, ...], FloatArray] = {}

    def _col(self, key: tuple[object, ...], make: Callable[[], FloatArray]) -> FloatArray:
        # ``make`` is called at once (never stored), so closures over loop variables are safe.
        if key not in self._cache:
            self._cache[key] = self.sig.lowpass(make())
        return self._cache[key]

    def torque(self, delay_s: float, limit_v: float | None = None) -> FloatArray:
        """K·L[sat(u)](t − d − h/2), full rate; ``limit_v`` a saturation's limit (None: no
        saturation, the command as logged: the drive's rail is never below it).

        The command is held over each sample period [t_k, t_k + h), so the torque centred on
        t_k (where the centred derivatives put α) is the mean of u_{k−1} and u_k: the samples
        are half a period late against the torque they apply (the logging convention, not a
        delay of the drive).
        """
        lim = self.rail_v if limit_v is None else clip_level_v({"saturation.limit": limit_v}, self.rail_v)
        u = self._col(("u", round(lim, 6)), lambda: np.clip(self.sig.u_v, -lim, lim))
        return self.gain * delayed(self.sig.t_s, u, delay_s + 0.5 * self.sig.dt_s)

    def load_alpha(self, structure: Structure) -> FloatArray | None:
        """Load-side acceleration for a two-mass structure, else None."""
        st = structure.settings
        if "compliance" in structure.effects:
            f, z = st["compliance.frequency"], st["compliance.damping"]
            return self._compliant_alpha(f, z)
        if "backlash" in structure.effects:
            w = st["backlash.width"]

            def make() -> FloatArray:
                return _play(self.sig.theta_rad, self.sig.dt_s, 0.5 * w, *self.load_fall)

            th_l = self._col(("play", round(w, 9), *self.load_fall), make)
            return np.gradient(np.gradient(th_l, self.sig.dt_s), self.sig.dt_s)
        return None

    def _compliant_alpha(self, f_hz: float, zeta: float) -> FloatArray:
        key = ("belt", round(f_hz, 6), round(zeta, 6))
        if key not in self._cache:
            w = 2 * math.pi * f_hz
            k_l, c_l = w * w * self.frac, 2 * zeta * w * self.frac
            # Bilinear transform of (c s + k)/(s² + c s + k), written out (scipy's is slow).
            q = 2.0 / self.sig.dt_s
            den = np.array([q * q + c_l * q + k_l, 2 * k_l - 2 * q * q, q * q - c_l * q + k_l])
            b = np.array([c_l * q + k_l, 2 * k_l, k_l - c_l * q]) / den[0]
            a = den / den[0]
            x = self.sig.alpha_rad_s2
            zi = signal.lfilter_zi(b, a) * x[0]
            self._cache[key] = np.asarray(signal.lfilter(b, a, x, zi=zi)[0], dtype=float)
        return self._cache[key]

    def columns(self, structure: Structure) -> list[Column]:
        """Every regression column of ``structure`` (full rate, filtered)."""
        s, om, th = self.sig, self.sig.omega_rad_s, self.sig.theta_rad
        st = structure.settings
        al_l = self.load_alpha(structure)
        cols: list[Column] = (
            [("Jm", s.alpha_rad_s2)] if al_l is None else [("Jm", s.alpha_rad_s2), ("Jl", al_l)]
        )
        cols += [("b", om), ("Fc", self._col(("sgn",), lambda: self.sgn))]
        for e in structure.effects:
            if e == "offset":
                cols.append(("offset", np.ones_like(om)))
            elif e == "coulomb_asymmetry":
                cols.append(("dFc", self._col(("neg",), lambda: -(om < 0).astype(float))))
            elif e == "viscous_asymmetry":
                cols.append(("db", self._col(("wneg",), lambda: np.where(om < 0, om, 0.0))))
            elif e == "gravity":
                cols.append(("g_s", self._col(("sin", 1.0), lambda: np.sin(th))))
                cols.append(("g_c", self._col(("cos", 1.0), lambda: np.cos(th))))
            elif e == "ripple":
                n = st["ripple.cycles_per_rev"]
                cols.append(("r_s", self._col(("sin", n), lambda: np.sin(n * th))))  # noqa: B023
                cols.append(("r_c", self._col(("cos", n), lambda: np.cos(n * th))))  # noqa: B023
            elif e == "stiction":
                vs = st["stiction.velocity"]
                strib = self._col(("strib", vs), lambda: np.exp(-((om / vs) ** 2)) * self.sgn)  # noqa: B023
                cols.append(("dFs", strib))
            elif is_generic(e):
                cols += self._generic(e, st, e == structure.linearized)[0]
        return cols

    def _generic(
        self, effect: str, settings: Mapping[str, float], linearized: bool
    ) -> tuple[list[Column], FloatArray]:
        """Filtered columns and rest torque of a generic effect (:func:`generic.columns`): its
        linear parameters, or all it fits when ``linearized`` (a Gauss–Newton step)."""
        eff = get_effect(effect)
        p = generic.point(eff, settings)
        names = generic.fitted_params(eff) if linearized else generic.linear_params(eff)
        key = ("generic", effect, linearized, *sorted(p.items()))
        if key not in self._cache:
            cols, rest = generic.columns(eff, p, self.sig.theta_rad, names)
            for name, c in cols:
                self._cache[(*key, name)] = self.sig.lowpass(c)
            # An effect linear in its parameters leaves only round-off here: skip the filter.
            size = max([float(np.max(np.abs(c))) for _, c in cols] + [1e-300])
            tiny = float(np.max(np.abs(rest))) <= 1e-9 * size
            self._cache[key] = np.zeros_like(rest) if tiny else self.sig.lowpass(rest)
        return [(n, self._cache[(*key, n)]) for n in names], self._cache[key]

    def fit(self, structure: Structure, n_eff: float | None = None, cv: bool = True) -> Regression:
        """Regress the torque of ``structure`` on its columns at the used samples."""
        cols = self.columns(structure)
        idx = self.sig.use
        x = np.column_stack([c[idx] for _, c in cols])
        st = structure.settings
        y = self.torque(
            st.get("delay.seconds", 0.0) if "delay" in structure.effects else 0.0,
            st.get("saturation.limit") if "saturation" in structure.effects else None,
        )
        for e in structure.effects:
            if is_generic(e):
                y = y - self._generic(e, st, e == structure.linearized)[1]
        return regress(tuple(n for n, _ in cols), x, y[idx], self.sig.fold[idx], n_eff, cv)


def model_params(
    model: AxisModel, structure: Structure, reg: Regression
) -> tuple[dict[str, float], dict[str, float]]:
    """Model parameters (full names, SI) and standard errors implied by a regression."""
    c = dict(zip(reg.names, reg.coef, strict=True))
    idx = {n: i for i, n in enumerate(reg.names)}

    def derived(coef: FloatArray) -> dict[str, float]:
        v = dict(zip(reg.names, coef, strict=True))
        out = {"inertia.J": v["Jm"] + v.get("Jl", 0.0), "viscous.b": v["b"], "coulomb.torque": v["Fc"]}
        if "offset" in v:
            out["offset.torque"] = v["offset"]
        if "dFc" in v:
            out["coulomb_asymmetry.negative"] = v["Fc"] + v["dFc"]
        if "db" in v:
            out["viscous_asymmetry.negative"] = v["b"] + v["db"]
        if "g_s" in v:
            out["gravity.torque"], out["gravity.phase"] = circular_fit(v["g_s"], v["g_c"])
        if "r_s" in v:
            out["ripple.amplitude"], out["ripple.phase"] = circular_fit(v["r_s"], v["r_c"])
        if "dFs" in v:
            out["stiction.static_torque"] = v["Fc"] + v["dFs"]
        out.update({n: x for n, x in v.items() if "." in n})  # generic effects: full names
        return out

    beta = np.array([c[n] for n in reg.names])
    values = derived(beta)
    # Standard errors by the delta method (numerical Jacobian of the derived parameters).
    keys = list(values)
    jac = np.zeros((len(keys), beta.size))
    for j in range(beta.size):
        h = 1e-6 * max(abs(beta[j]), 1e-9)
        b2 = beta.copy()
        b2[j] += h
        d2 = derived(b2)
        jac[:, j] = [(d2[k] - values[k]) / h for k in keys]
    var = np.einsum("ij,jk,ik->i", jac, reg.cov, jac)
    stderr = {
        k: float(math.sqrt(max(v, 0.0))) if np.isfinite(v) else math.inf
        for k, v in zip(keys, var, strict=True)
    }
    for k, v in structure.settings.items():
        if k.split(".")[0] in structure.effects and k not in values:
            values[k] = v
    del idx
    clipped = {}
    for k, v in values.items():
        p = get_param(k)
        clipped[k] = float(min(max(v, p.lower), p.upper))
    return clipped, stderr


def screen(
    effect: str,
    design: TorqueDesign,
    model: AxisModel,
    base: Structure,
    base_reg: Regression,
    structure: Structure,
    extra_dof: int,
    detail: Mapping[str, float] | None = None,
    reg: Regression | None = None,
) -> Screen:
    """Score ``structure`` (``base`` plus ``effect``) against the base regression."""
    if reg is None or not reg.sse_fold.any():  # grid searches fit without the held-out folds
        reg = design.fit(structure, base_reg.n_eff)
    params, stderr = model_params(model, structure, reg)
    gain = 1.0 - reg.sse_cv / base_reg.sse_cv if base_reg.sse_cv > 0 else 0.0
    p = improvement_p_value(base_reg, reg, extra_dof, effective_samples(reg.residual))
    folds = bool(np.all(reg.sse_fold < base_reg.sse_fold))
    return Screen(effect, structure, reg, params, stderr, gain, p, folds, dict(detail or {}))


#: The low-passes tried for the sliding Coulomb torque, as fractions of the screening's cut-off.
SLIDING_CUTOFF_FRACTIONS = (1.0, 0.5, 0.25)


def sliding_coulomb(design: TorqueDesign, model: AxisModel, reg: Regression) -> tuple[float, float]:
    """The Coulomb torque of the moving data and its standard error (N·m), from the torque
    regression of ``model``'s structure at the low-pass that determines it best.

    Every column passes through the same filter, so the filter cancels from the friction terms
    at any cut-off; what the cut-off sets is the noise of the regressor α: the encoder's step,
    differentiated twice, grows as the cut-off to the power 2.5 and on a coarse or slowly
    sampled encoder swamps the acceleration, which both dilutes the inertia towards zero and
    leaves the Coulomb torque poorly determined (truthgen 8181 held-out stiction-000, 500
    counts at 250 Hz: at 50 Hz the inertia came out at 0.0002 for 0.0033 and Coulomb
    0.042 ± 0.017 N·m; at 12.5 Hz 0.0029 and 0.045 ± 0.003, true 0.048). A lower cut-off
    widens the guard band around rests and leaves fewer samples, so the regression's own
    standard error decides between them: the one that determines Coulomb best is kept
    (``reg``, the screening's, first).
    """
    values, stderr = model_params(model, Structure.of(model), reg)
    best = (float(values["coulomb.torque"]), float(stderr.get("coulomb.torque", math.inf)))
    sig = design.sig
    for frac in SLIDING_CUTOFF_FRACTIONS[1:]:
        meas = Measurement(sig.t_s, sig.u_v, sig.theta_raw_rad)
        try:
            low = prepare_signals(meas, frac * sig.cutoff_hz)
        except DataError:
            break  # too few moving samples at this low-pass (and at any lower one)
        other = TorqueDesign(low, design.gain, design.frac, design.load_fall)
        v, se = model_params(model, Structure.of(model), other.fit(Structure.of(model)))
        c, c_se = float(v["coulomb.torque"]), float(se.get("coulomb.torque", math.inf))
        if math.isfinite(c_se) and c_se < best[1]:
            best = (c, c_se)
    return best


__all__ = [
    "NONLINEAR",
    "Screen",
    "Structure",
    "TorqueDesign",
    "gravity_fall",
    "load_fall",
    "model_params",
    "screen",
    "sliding_coulomb",
]
