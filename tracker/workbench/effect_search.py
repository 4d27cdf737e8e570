"""Search each missing effect's nonlinear parameter by inverse dynamics and score the best one.

One function per effect family; :func:`screen_missing_effects` runs them all for a model.
Grids are coarse-then-fine so that every candidate costs a few tens of milliseconds.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from tracker.errors import JobCancelled
from tracker.plant.model import AxisModel
from tracker.units import AMPLIFIER_LIMIT_V
from tracker.workbench.idim import Regression
from tracker.workbench.screening import Screen, Structure, TorqueDesign, screen

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
MIN_BACKLASH_COUNTS = 4


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


def ripple_periodogram(residual: FloatArray, theta_rad: FloatArray, n_max: int) -> FloatArray:
    """Power of the residual at n = 0..n_max cycles per revolution of θ. Shape (n_max + 1,)."""
    z = np.exp(1j * theta_rad)
    zn = np.ones_like(z)
    r = residual - residual.mean()
    power = np.zeros(n_max + 1)
    for n in range(1, n_max + 1):
        zn = zn * z
        power[n] = abs(np.dot(r, zn)) ** 2 / r.size
    return power


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
        elif effect == "ripple":
            th = sig.theta_rad[sig.use]
            span = float(np.ptp(th))
            speed = float(np.median(np.abs(sig.omega_rad_s[sig.use]))) or 1.0
            n_max = int(min(RIPPLE_MAX_CYCLES, max(4, 2 * math.pi * sig.cutoff_hz / speed)))
            power = ripple_periodogram(base_reg.residual, th, n_max)
            power[:2] = 0.0  # n = 1 is gravity's shape
            top = np.argsort(power)[::-1][:3]
            structs = [base.plus("ripple", **{"ripple.cycles_per_rev": float(n)}) for n in top]
            st, reg, _ = _best(design, structs, ne)
            n_best = st.settings["ripple.cycles_per_rev"]
            med = float(np.median(power[2:])) or 1e-30
            detail = {
                "cycles_per_rev": n_best,
                "peak_ratio": float(power[int(n_best)] / med),
                "span_rad": span,
            }
            out[effect] = screen(effect, design, model, base, base_reg, st, 3, detail, reg)
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
            grid = np.unique(np.clip(np.quantile(au, np.linspace(0.6, 0.995, 16)), 0.05, AMPLIFIER_LIMIT_V))
            grid = grid[grid < 0.999 * AMPLIFIER_LIMIT_V]
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
            step = max(sig.encoder_step_rad, 1e-5)
            # Below a few encoder counts a dead band is indistinguishable from quantization.
            grid = np.geomspace(MIN_BACKLASH_COUNTS * step, 0.1, 12)
            st, reg, w = _refine_1d(
                design, lambda v: base.plus("backlash", **{"backlash.width": v}), grid, ne
            )
            out[effect] = screen(effect, design, model, base, base_reg, st, 3, {"width": w}, reg)
        elif effect == "compliance":
            out[effect] = _screen_compliance(design, model, base, base_reg)
    return out


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


__all__ = ["SCREENED", "ripple_periodogram", "screen_missing_effects"]
