"""Search each missing effect's nonlinear parameter by inverse dynamics and score the best one.

One function per effect family; :func:`screen_missing_effects` runs them all for a model.
Grids are coarse-then-fine so that every candidate costs a few tens of milliseconds. Effects
that are not built in are screened by :func:`screen_generic` on their own declared grids.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from tracker.errors import JobCancelled
from tracker.plant.effects import generic_effects, get_effect
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.screening import Screen, Structure, TorqueDesign, gravity_fall, screen
from tracker.workbench.fit import generic
from tracker.workbench.fit.search import whole_is_enough
from tracker.workbench.measurements.idim import Regression, Signals

FloatArray = NDArray[np.float64]

# Effects screened here (quantization is a sensor effect: it changes no prediction).
SCREENED = (
    "offset",
    "coulomb_asymmetry",
    "viscous_asymmetry",
    "gravity",
    "ripple",
    "stiction",
    "delay",
    "saturation",
    "backlash",
    "compliance",
)
MAX_DELAY_S = 0.1
RIPPLE_MAX_CYCLES = 500
# Passes of gravity's screening on a dead-band model with the load falling under the gravity the
# previous pass found (each moves it towards a fixed point; the second changes little).
GAP_FALL_PASSES = 2
# A play as narrow as the spread of the reading is what the reading flickering at a reversal (a
# count either way, or the angle noise) looks like to the dead-band reconstruction: it is the
# null a real dead band must beat (see :func:`screen_backlash`). The spread is at least this many
# counts, and at least this many standard deviations of the reading about the low-passed angle.
FLICKER_MIN_COUNTS = 2.0
FLICKER_SIGMAS = 6.0  # ±3σ
FLICKER_PLAYS = (0.25, 0.5, 0.75, 1.0)  # the null's plays, as fractions of the spread


def _best(
    design: TorqueDesign, structures: list[Structure], n_eff: float
) -> tuple[Structure, Regression, list[float]]:
    regs = [design.fit(s, n_eff, cv=False) for s in structures]
    sses = [r.sse for r in regs]
    i = int(np.argmin(sses))
    return structures[i], regs[i], sses


def _refine_1d(
    design: TorqueDesign,
    make: Callable[[float], Structure],
    grid: FloatArray,
    n_eff: float,
    log: bool = True,
    steps: int = 6,
) -> tuple[Structure, Regression, float]:
    """Grid search then golden-section refinement of one nonlinear setting (by full-data SSE)."""
    structs = [make(float(v)) for v in grid]
    _, _, sses = _best(design, structs, n_eff)
    i = int(np.argmin(sses))
    lo, hi = grid[max(0, i - 1)], grid[min(grid.size - 1, i + 1)]
    f = (lambda v: math.log(v)) if log else (lambda v: v)
    g = (lambda v: math.exp(v)) if log else (lambda v: v)
    a, b = f(lo), f(hi)
    r = (math.sqrt(5) - 1) / 2
    best_v, best_sse = float(grid[i]), sses[i]
    for _ in range(steps):
        c, d = b - r * (b - a), a + r * (b - a)
        sc, sd = design.fit(make(g(c)), n_eff, cv=False).sse, design.fit(make(g(d)), n_eff, cv=False).sse
        for v, s in ((g(c), sc), (g(d), sd)):
            if s < best_sse:
                best_v, best_sse = v, s
        if sc < sd:
            b = d
        else:
            a = c
    st = make(best_v)
    return st, design.fit(st, n_eff), best_v


def ripple_periodogram(residual: FloatArray, theta_rad: FloatArray, cycles: FloatArray) -> FloatArray:
    """Power of the residual at each (real, not only whole) number of ``cycles`` per revolution
    of θ; ``cycles`` must be evenly spaced. Returns shape (cycles.size,)."""
    r = residual - residual.mean()
    power = np.empty(cycles.size)
    if cycles.size == 0:
        return power
    step = float(cycles[1] - cycles[0]) if cycles.size > 1 else 0.0
    rz = r * np.exp(1j * cycles[0] * theta_rad)
    z = np.exp(1j * step * theta_rad)
    for i in range(cycles.size):
        if i and i % 256 == 0:  # re-anchor: the running product drifts slowly
            rz = r * np.exp(1j * cycles[i] * theta_rad)
        acc = rz.sum()
        power[i] = (acc.real * acc.real + acc.imag * acc.imag) / r.size
        rz *= z
    return power


def _ripple_peaks(power: FloatArray, cycles: FloatArray, width: float, count: int) -> list[float]:
    """The ``count`` highest local peaks of a periodogram, at least ``width`` apart."""
    order = np.argsort(power)[::-1]
    peaks: list[float] = []
    for i in order:
        n = float(cycles[i])
        if all(abs(n - p) >= width for p in peaks):
            peaks.append(n)
        if len(peaks) == count:
            break
    return peaks


def screen_missing_effects(
    design: TorqueDesign,
    model: AxisModel,
    base: Structure,
    base_reg: Regression,
    cancel: Callable[[], bool] | None = None,
) -> dict[str, Screen]:
    """Screen every effect of :data:`SCREENED` the model does not have yet."""
    out: dict[str, Screen] = {}
    ne = base_reg.n_eff
    sig = design.sig
    for effect in SCREENED:
        if cancel is not None and cancel():
            raise JobCancelled("diagnosis cancelled while screening effects")
        if model.has(effect):
            continue
        if effect in ("offset", "coulomb_asymmetry", "viscous_asymmetry", "gravity"):
            st = base.plus(effect)
            out[effect] = screen(effect, design, model, base, base_reg, st, 2 if effect == "gravity" else 1)
            if effect == "gravity" and "backlash" in base.effects:
                out[effect] = _gravity_behind_gap(design, model, base, base_reg, out[effect])
        elif effect == "ripple":
            out[effect] = _screen_ripple(design, model, base, base_reg)
        elif effect == "stiction":
            grid = np.geomspace(0.005, 0.5, 10)
            st, reg, vs = _refine_1d(
                design, lambda v: base.plus("stiction", **{"stiction.velocity": v}), grid, ne, steps=4
            )
            out[effect] = screen(effect, design, model, base, base_reg, st, 2, {"velocity": vs}, reg)
        elif effect == "delay":
            grid = np.arange(0.0, MAX_DELAY_S + 1e-9, max(sig.dt_s, 0.002))
            st, reg, d = _refine_1d(
                design, lambda v: base.plus("delay", **{"delay.seconds": v}), grid, ne, log=False
            )
            out[effect] = screen(effect, design, model, base, base_reg, st, 2, {"seconds": d}, reg)
        elif effect == "saturation":
            au = np.abs(sig.u_v[sig.use])
            # Levels at the drive's rail clip nothing the log commands.
            rail = design.rail_v
            grid = np.unique(np.clip(np.quantile(au, np.linspace(0.6, 0.995, 16)), 0.05, rail))
            grid = grid[grid < 0.999 * rail]
            if grid.size < 3:
                continue
            st, reg, lim = _refine_1d(
                design, lambda v: base.plus("saturation", **{"saturation.limit": v}), grid, ne
            )
            above = float(np.mean(np.abs(sig.u_v) > lim))
            out[effect] = screen(
                effect, design, model, base, base_reg, st, 2, {"limit": lim, "above": above}, reg
            )
        elif effect == "backlash":
            out[effect] = screen_backlash(design, model, base, base_reg)
        elif effect == "compliance":
            out[effect] = _screen_compliance(design, model, base, base_reg)
    for effect in generic_effects():
        if cancel is not None and cancel():
            raise JobCancelled("diagnosis cancelled while screening effects")
        if not model.has(effect):
            out[effect] = screen_generic(design, model, base, base_reg, effect)
    return out


def _screen_ripple(design: TorqueDesign, model: AxisModel, base: Structure, base_reg: Regression) -> Screen:
    """Ripple: cycles per revolution searched on a continuous scale (cogging seen through a
    gear is rarely a whole number per load revolution), from the residual torque's periodogram
    against θ, then refined on the regression itself."""
    sig = design.sig
    ne = base_reg.n_eff
    th = sig.theta_rad[sig.use]
    span = max(float(np.ptp(th)), 1e-3)
    # The low-pass keeps a ripple only while n·|ω| stays below the cut-off: the slow quarter
    # of the motion sets how many cycles per revolution can be seen at all.
    slow = float(np.percentile(np.abs(sig.omega_rad_s[sig.use]), 25)) or 1.0
    n_max = float(min(RIPPLE_MAX_CYCLES, max(4.0, 2 * math.pi * sig.cutoff_hz / slow)))
    resolution = 2 * math.pi / span  # periodogram peak width in cycles per revolution
    cycles = np.arange(2.0, n_max + 1e-9, min(0.25, resolution / 8.0))
    power = ripple_periodogram(base_reg.residual, th, cycles)
    best: tuple[float, Structure, Regression, float] | None = None
    for n0 in _ripple_peaks(power, cycles, resolution, 3):
        local = np.linspace(max(2.0, n0 - 0.5 * resolution), max(2.0, n0 + 0.5 * resolution), 5)
        st, reg, n = _refine_1d(
            design, lambda v: base.plus("ripple", **{"ripple.cycles_per_rev": v}), local, ne, log=False
        )
        if best is None or reg.sse < best[0]:
            best = (reg.sse, st, reg, n)
    assert best is not None
    sse_best, st, reg, n_best = best
    whole = float(max(2, round(n_best)))
    st_whole = base.plus("ripple", **{"ripple.cycles_per_rev": whole})
    reg_whole = design.fit(st_whole, ne)
    if whole_is_enough(reg_whole.sse, sse_best, ne):
        st, reg, n_best = st_whole, reg_whole, whole
    med = float(np.median(power)) or 1e-30
    detail = {
        "cycles_per_rev": n_best,
        "peak_ratio": float(ripple_periodogram(base_reg.residual, th, np.array([n_best]))[0] / med),
        "span_rad": span,
    }
    return screen("ripple", design, model, base, base_reg, st, 3, detail, reg)


def screen_backlash(design: TorqueDesign, model: AxisModel, base: Structure, base_reg: Regression) -> Screen:
    """Backlash: the dead band's width by the regression with the load reconstructed behind it.

    A play as wide as the reading's flicker explains much of the residual torque of any log (the
    count, or the angle noise, flickers at reversals and the load "coasts" through the flicker,
    which smooths the acceleration's staircase), with no dead band at all. So the widths are
    searched from the flicker's spread (:func:`reading_spread_rad`) up, and
    ``detail["beyond_flicker"]`` is the share of the residual torque the best width explains
    beyond the best play within that spread: a real dead band's motor travels its whole width at
    every reversal, which a flicker does not.
    """
    sig = design.sig
    ne = base_reg.n_eff
    spread = reading_spread_rad(sig)

    def make(v: float) -> Structure:
        return base.plus("backlash", **{"backlash.width": v})

    flicker = min(design.fit(make(f * spread), ne, cv=False).sse for f in FLICKER_PLAYS)
    grid = np.geomspace(spread, max(0.1, 4.0 * spread), 12)
    st, reg, w = _refine_1d(design, make, grid, ne)
    beyond = 1.0 - reg.sse / flicker if flicker > 0 else 0.0
    detail = {"width": w, "beyond_flicker": beyond, "flicker_rad": spread}
    return screen("backlash", design, model, base, base_reg, st, 3, detail, reg)


def _gravity_behind_gap(
    design: TorqueDesign, model: AxisModel, base: Structure, base_reg: Regression, scr: Screen
) -> Screen:
    """Gravity on a model with a dead band: between the flanks the load falls under the very
    unbalance being screened (:func:`screening.load_fall`), which a coasting load's
    reconstruction leaves out. Screened again with the load falling under the gravity found,
    while that fits the torque better (:data:`GAP_FALL_PASSES` at most); against the present
    model's own regression, as every candidate is."""
    for _ in range(GAP_FALL_PASSES):
        fall = gravity_fall(scr.params, design.frac)
        if fall[0] <= 0.0:
            break
        falling = TorqueDesign(design.sig, design.gain, design.frac, fall)
        nxt = screen("gravity", falling, model, base, base_reg, scr.structure, 2)
        if nxt.regression.sse >= scr.regression.sse:
            break
        scr = nxt
    return scr


def reading_spread_rad(sig: Signals) -> float:
    """How far the encoder's reading spreads about the true angle (rad): the larger of
    :data:`FLICKER_MIN_COUNTS` counts and :data:`FLICKER_SIGMAS` robust standard deviations of
    the reading about the low-passed angle (quantization and angle noise together)."""
    step = max(sig.encoder_step_rad, 1e-5)
    r = sig.theta_raw_rad - sig.theta_rad
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    return max(FLICKER_MIN_COUNTS * step, FLICKER_SIGMAS * sigma)


def _screen_compliance(
    design: TorqueDesign, model: AxisModel, base: Structure, base_reg: Regression
) -> Screen:
    ne = base_reg.n_eff
    f_max = min(300.0, 2.0 * design.sig.cutoff_hz)
    freqs = np.geomspace(1.0, f_max, 14)
    best: tuple[float, float, float] = (math.inf, 0.0, 0.0)
    for z in (0.05, 0.15, 0.4):
        for f in freqs:
            st = base.plus("compliance", **{"compliance.frequency": f, "compliance.damping": z})
            sse = design.fit(st, ne, cv=False).sse
            if sse < best[0]:
                best = (sse, float(f), z)
    _, f0, z0 = best

    def make_f(v: float) -> Structure:
        return base.plus("compliance", **{"compliance.frequency": v, "compliance.damping": z0})

    i = int(np.argmin(np.abs(freqs - f0)))
    local = freqs[max(0, i - 1) : i + 2]
    _, _, f1 = _refine_1d(design, make_f, local, ne, steps=5)

    def make_z(v: float) -> Structure:
        return base.plus("compliance", **{"compliance.frequency": f1, "compliance.damping": v})

    st, reg, z1 = _refine_1d(design, make_z, np.array([0.5 * z0, z0, 2 * z0]), ne, steps=4)
    return screen("compliance", design, model, base, base_reg, st, 4, {"frequency": f1, "damping": z1}, reg)


def screen_generic(
    design: TorqueDesign, model: AxisModel, base: Structure, base_reg: Regression, effect: str
) -> Screen:
    """A generic effect: its searched parameters over the product of their declared grids, each
    then refined by golden section; its linear parameters by the regression; then Gauss–Newton
    steps on every parameter it is not linear in (:func:`generic.gauss_newton`)."""
    eff = get_effect(effect)
    ne = base_reg.n_eff
    held = {k: v for k, v in generic.defaults(eff).items() if k in generic.held_params(eff)}

    def make(values: Mapping[str, float]) -> Structure:
        return base.plus(effect, **{**held, **values})

    chosen: dict[str, float] = {}
    grids = {f"{effect}.{k}": np.asarray(v, dtype=float) for k, v in eff.search.items()}
    if grids:
        names = list(grids)
        combos = [dict(zip(names, c, strict=True)) for c in itertools.product(*grids.values())]
        sses = [design.fit(make(c), ne, cv=False).sse for c in combos]
        chosen = {k: float(v) for k, v in combos[int(np.argmin(sses))].items()}
        for name, grid in grids.items():
            i = int(np.argmin(np.abs(grid - chosen[name])))
            local = grid[max(0, i - 1) : i + 2]
            log = bool(np.all(grid > 0) and grid.max() > 10 * grid.min())
            _, _, chosen[name] = _refine_1d(
                design, lambda v: make({**chosen, name: v}), local, ne, log=log  # noqa: B023
            )
    st = make(chosen)
    st, _ = generic.gauss_newton(design, st, design.fit(st, ne, cv=False), effect, ne)
    detail = {n: st.settings[n] for n in generic.nonlinear_params(eff)}
    scr = screen(effect, design, model, base, base_reg, st, generic.param_count(effect), detail)
    return replace(scr, stderr={**scr.stderr, **generic.held_stderr(design, st, scr.regression, effect, ne)})


__all__ = ["SCREENED", "ripple_periodogram", "screen_backlash", "screen_generic", "screen_missing_effects"]
