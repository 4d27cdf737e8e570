"""Starting values for the fitter: searches for discrete and nonlinear parameters, then linear LS.

Gradient methods need a start near the answer and cannot move a discrete parameter at all.
Here each nonlinear parameter gets a search of its own, on the cheapest criterion that sees it:

* ``ripple.cycles_per_rev``: the residual torque's spectrum over θ (a Fourier projection on
  sin nθ, cos nθ for every whole n the data can resolve); the strongest line wins.
* ``delay.seconds``, ``saturation.limit``, ``stiction.velocity``: a grid on the inverse-dynamics
  error (each point a linear least squares over the linear parameters).
* ``backlash.width``, ``compliance.frequency``: a grid on the k-step prediction error (they act
  through a hidden state, so only a simulation sees them).

Then the linear parameters come from inverse dynamics, and the start is whichever of that and
the model's own values predicts better.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from tracker.errors import ConfigError
from tracker.plant.effects import BASE_EFFECTS, CATALOGUE, get_param, is_generic
from tracker.plant.model import AxisModel
from tracker.workbench.fit.torques import (
    fit_inverse_dynamics,
    linear_generic_params,
    moving_mask,
    replace_params,
    residual_torque_nm,
)
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.idim import effective_samples
from tracker.workbench.measurements.observed import observed_cost
from tracker.workbench.measurements.states import StateEstimate, encoder_step_rad

FloatArray = NDArray[np.float64]

MAX_RIPPLE_SAMPLES = 8000
DELAY_GRID_S = (0.0, 0.002, 0.005, 0.01, 0.015, 0.02, 0.03, 0.045, 0.065, 0.09, 0.12, 0.16)
STRIBECK_GRID = (0.02, 0.05, 0.1, 0.2, 0.4)  # × the 95th-percentile speed
SATURATION_GRID = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)  # × max |u|
# Backlash widths: 1 to 300 encoder counts, ratio 1.25 (the cost has a basin about ±20 % wide).
BACKLASH_GRID_COUNTS = tuple(float(x) for x in np.geomspace(1.0, 300.0, 26))
# Belt resonance: ratio 1.1 (the k-step cost's basin is only about ±10 % wide), then FINE_GRID.
COMPLIANCE_GRID_HZ = tuple(float(x) for x in np.geomspace(0.5, 300.0, 68))
FINE_GRID = tuple(float(x) for x in np.linspace(0.88, 1.12, 13))
COMPLIANCE_DAMPING_GRID = (0.02, 0.05, 0.1, 0.2, 0.4, 0.8)
# Dampings tried at every coarse frequency (a lightly damped basin is deep only near its ζ).
COARSE_DAMPING_GRID = (0.05, 0.15, 0.4)
# Basins of the coarse frequency profile refined (the true one need not be the lowest there).
RESONANCE_BASINS = 3
# After the damping is set: frequency steps of 2 % (the basin is ±ζ wide, ζ down to ~0.04).
RESONANCE_FINE_GRID = tuple(float(x) for x in np.linspace(0.94, 1.06, 7))
# Low-pass of the rigid-body inverse dynamics for two-mass models (Hz).
TWO_MASS_ID_CUTOFF_HZ = 2.0
# Parameters of effects that act through a hidden state (searched by prediction only).
HIDDEN_STATE_PARAMS = ("backlash.width", "compliance.frequency", "compliance.damping")
# Grids on the prediction error use every GRID_WINDOW_STRIDE-th window (4× cheaper).
GRID_WINDOW_STRIDE = 4


@dataclass(frozen=True, slots=True)
class StartValues:
    """The fitter's starting model and the inverse-dynamics relative error (%) behind it.

    ``alternatives``: other starts in other basins of a multimodal parameter (a belt resonance),
    best first; the fitter runs a short fit from each and goes on from the best. ``rivals``:
    the start at other local minima of a searched profile (delay); the fitter checks after the
    fit whether one of them fits as well, and widens the standard errors if so.
    """

    model: AxisModel
    id_error_percent: float
    alternatives: tuple[AxisModel, ...] = ()
    rivals: tuple[AxisModel, ...] = ()


def window_cost(
    meas: Measurement,
    est: StateEstimate,
    model: AxisModel,
    k: int,
    stride: int = 1,
    abandon_above: float = math.inf,
) -> float:
    """Mean squared k-step window prediction error (rad²) of ``model`` (every ``stride``-th
    window); infinite as soon as it is sure to exceed ``abandon_above`` (a search's best so far)."""
    starts = np.arange(0, meas.n - k - 1, k * stride, dtype=np.int64)
    return observed_cost(model, meas, est, starts, k + 1, abandon_above)


def ripple_spectrum(
    theta_rad: FloatArray, torque_nm: FloatArray, n_max: int = 500
) -> tuple[NDArray[np.int64], FloatArray]:
    """Amplitude (N·m) of the torque's sin/cos nθ component for each resolvable whole n.

    Returns (cycles, amplitude), shape (m,) each. n must fit two periods in the θ range seen and
    be resolved by the sample spacing in θ.
    """
    th = np.asarray(theta_rad, dtype=float)
    tq = np.asarray(torque_nm, dtype=float) - float(np.mean(torque_nm))
    span = float(th.max() - th.min())
    if th.size < 50 or span <= 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    n_lo = max(1, int(math.ceil(4.0 * math.pi / span)))
    step = float(np.percentile(np.abs(np.diff(th)), 95)) or span
    n_hi = int(min(n_max, math.pi / (2.0 * step)))
    if n_hi < n_lo:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    if th.size > MAX_RIPPLE_SAMPLES:
        pick = np.linspace(0, th.size - 1, MAX_RIPPLE_SAMPLES).astype(np.int64)
        th, tq = th[pick], tq[pick]
    ns = np.arange(n_lo, n_hi + 1, dtype=np.int64)
    amps = np.empty(ns.size)
    for i, n in enumerate(ns):
        a = np.column_stack([np.sin(n * th), np.cos(n * th)])
        coef, *_ = np.linalg.lstsq(a, tq, rcond=None)
        amps[i] = math.hypot(coef[0], coef[1])
    return ns, amps


def find_ripple_cycles(meas: Measurement, est: StateEstimate, model: AxisModel) -> float:
    """Whole cycles per revolution of the strongest θ-periodic residual torque (the model's
    value when the data cannot resolve any)."""
    base = model.without_effect("ripple")
    free = [
        k
        for k in base.free_param_names()
        if k.split(".")[0] not in ("delay", "saturation", "backlash", "compliance")
    ]
    fitted = replace_params(base, fit_inverse_dynamics(meas, est, base, free).params)
    mov = moving_mask(est.omega_rad_s)
    tq = residual_torque_nm(meas, est, fitted)[mov]
    th = est.theta_rad[mov]
    ns, amps = ripple_spectrum(th, tq)
    if ns.size == 0:
        return float(model.params["ripple.cycles_per_rev"])
    return _refine_cycles(th, tq, float(ns[int(np.argmax(amps))]))


def _refine_cycles(theta_rad: FloatArray, torque_nm: FloatArray, n0: float) -> float:
    """The real number of cycles per revolution near ``n0`` whose sin/cos fit explains most:
    cogging seen through a gear (e.g. 2 × 17.01 per load revolution) is rarely whole."""
    th, tq = theta_rad, torque_nm - float(np.mean(torque_nm))
    if th.size > MAX_RIPPLE_SAMPLES:
        pick = np.linspace(0, th.size - 1, MAX_RIPPLE_SAMPLES).astype(np.int64)
        th, tq = th[pick], tq[pick]
    grid = np.arange(max(1.0, n0 - 1.0), n0 + 1.0 + 1e-9, 0.02)

    def sse(n: float) -> float:
        a = np.column_stack([np.sin(n * th), np.cos(n * th), np.ones_like(th)])
        coef, *_ = np.linalg.lstsq(a, tq, rcond=None)
        r = tq - a @ coef
        return float(r @ r)

    sses = np.array([sse(float(n)) for n in grid])
    best = float(grid[int(np.argmin(sses))])
    whole = float(max(1, round(best)))
    return whole if whole_is_enough(sse(whole), float(sses.min()), effective_samples(tq)) else best


def whole_is_enough(sse_whole: float, sse_best: float, n_eff: float) -> bool:
    """Whether a whole number of cycles per revolution explains the data as well as the best
    real number, within chance (F-test at 1 % for the one extra degree of freedom on ``n_eff``
    effectively independent samples): the simpler story — a ripple of the load itself — wins."""
    if sse_best <= 0.0:
        return sse_whole <= 0.0
    f = (sse_whole - sse_best) / (sse_best / max(1.0, n_eff - 4.0))
    return bool(f < stats.f.ppf(0.99, 1, max(1.0, n_eff - 4.0)))


def _cutoff_hz(model: AxisModel) -> float | None:
    """Rigid-body inverse dynamics of a two-mass axis: keep well below the belt resonance."""
    if model.has("compliance") or model.has("backlash"):
        return TWO_MASS_ID_CUTOFF_HZ
    return None


def _id_error(meas: Measurement, est: StateEstimate, model: AxisModel, free: Sequence[str]) -> float:
    return fit_inverse_dynamics(meas, est, model, free, cutoff_hz=_cutoff_hz(model)).relative_error_percent


def _grid_on_id(
    meas: Measurement,
    est: StateEstimate,
    model: AxisModel,
    name: str,
    grid: Sequence[float],
    free: Sequence[str],
) -> AxisModel:
    prm = get_param(name)
    best, best_err = model, math.inf
    for v in grid:
        v = min(max(v, prm.lower), prm.upper)
        cand = replace_params(model, {name: v})
        err = _id_error(meas, est, cand, free)
        if err < best_err:
            best, best_err = cand, err
    return best


def _delay_rivals(
    meas: Measurement, est: StateEstimate, model: AxisModel, free: Sequence[str]
) -> list[float]:
    """Delays at the other local minima of the inverse-dynamics error over the delay grid.

    Stiction and a delay both act at reversals, J and a delay both shape the answer to a step:
    on a short or coarse log two delays far apart can explain it about equally well. Returns
    the grid values at local minima other than the best (at most two), best first."""
    prm = get_param("delay.seconds")
    errs = []
    for v in DELAY_GRID_S:
        cand = replace_params(model, {"delay.seconds": min(max(v, prm.lower), prm.upper)})
        try:
            errs.append(_id_error(meas, est, cand, free))
        except ConfigError:
            errs.append(math.inf)
    idx = _local_minima(errs, 3)
    chosen = model.params["delay.seconds"]
    # Always also "no transport delay": none, or one sample (a computational latency, the
    # README's logging convention); the fit then asks whether the data reject them.
    conventions = [0.0, meas.dt_s]
    return [
        v for v in [*(DELAY_GRID_S[i] for i in idx[1:]), *conventions] if abs(v - chosen) > 0.5 * meas.dt_s
    ]


def grid_on_prediction(
    meas: Measurement,
    est: StateEstimate,
    model: AxisModel,
    name: str,
    grid: Sequence[float],
    k: int,
    stride: int = GRID_WINDOW_STRIDE,
) -> AxisModel:
    """``model`` with ``name`` set to the grid value (or its own) of least k-step window cost."""
    return _grid_with_cost(meas, est, model, name, grid, k, stride)[0]


def _grid_with_cost(
    meas: Measurement,
    est: StateEstimate,
    model: AxisModel,
    name: str,
    grid: Sequence[float],
    k: int,
    stride: int = GRID_WINDOW_STRIDE,
    model_cost: float | None = None,
) -> tuple[AxisModel, float]:
    """:func:`grid_on_prediction` and the winner's cost; ``model_cost``: ``model``'s own, when
    already known (at this ``stride``)."""
    prm = get_param(name)
    best = model
    best_cost = window_cost(meas, est, model, k, stride) if model_cost is None else model_cost
    # A value clipped to a bound (a fine grid around a stiff belt at 300 Hz) or the model's own
    # is judged once: the same candidate again can only tie, and a tie never replaces the best.
    seen = {model.params[name]}
    for v in grid:
        v = min(max(v, prm.lower), prm.upper)
        if v in seen:
            continue
        seen.add(v)
        cand = replace_params(model, {name: v})
        cost = window_cost(meas, est, cand, k, stride, best_cost)
        if cost < best_cost:
            best, best_cost = cand, cost
    return best, best_cost


def search_start(
    meas: Measurement, est: StateEstimate, model: AxisModel, free: Sequence[str], k: int
) -> StartValues:
    """Starting values for the fit of ``free`` (full names) at horizon ``k`` samples."""
    m = model
    if m.has("quantization"):
        q = encoder_step_rad(meas.theta_rad)
        if 0.0 < q <= get_param("quantization.step").upper:
            m = replace_params(m, {"quantization.step": q})
    linear_free = [
        n for n in free if n.split(".")[0] not in ("delay", "saturation", "backlash", "compliance")
    ]
    linear_free = [
        n
        for n in linear_free
        if n not in ("stiction.velocity", "gravity.phase", "ripple.phase", "ripple.cycles_per_rev")
    ]
    # Generic effects: only the parameters their torque is linear in (the rest: searched, below).
    linear_free = [
        n for n in linear_free if not is_generic(n.split(".")[0]) or n in linear_generic_params(m, free)
    ]
    if m.has("ripple") and ("ripple.amplitude" in free or "ripple.cycles_per_rev" in free):
        m = replace_params(m, {"ripple.cycles_per_rev": find_ripple_cycles(meas, est, m)})
    w95 = float(np.percentile(np.abs(est.omega_rad_s), 95)) or 1.0
    umax = float(np.max(np.abs(meas.u_v)))
    rival_delays: list[float] = []
    try:
        if "delay.seconds" in free:
            m = _grid_on_id(meas, est, m, "delay.seconds", DELAY_GRID_S, linear_free)
            rival_delays = _delay_rivals(meas, est, m, linear_free)
        if "saturation.limit" in free and umax > 0:
            m = _grid_on_id(
                meas, est, m, "saturation.limit", [f * umax for f in SATURATION_GRID], linear_free
            )
        if "stiction.velocity" in free:
            m = _grid_on_id(meas, est, m, "stiction.velocity", [f * w95 for f in STRIBECK_GRID], linear_free)
        for name, grid in _generic_grids(m, free):
            m = _grid_on_id(meas, est, m, name, grid, linear_free)
        idf = fit_inverse_dynamics(meas, est, m, linear_free, cutoff_hz=_cutoff_hz(m))
    except ConfigError:
        idf = None
    # Inverse dynamics fits gravity and ripple as (T cos φ, T sin φ): keep the phase it found with
    # the amplitude (a torque at the wrong phase predicts worse than none at all).
    from_id = (*linear_free, *(n for n in ("gravity.phase", "ripple.phase") if n in free))
    m_id = replace_params(m, {k_: v for k_, v in idf.params.items() if k_ in from_id}) if idf else m
    if "stiction.static_torque" in free and m_id.has("stiction"):
        # Break-away torque must be at least Coulomb to mean anything (inverse dynamics hardly sees it).
        fc = m_id.params["coulomb.torque"]
        if m_id.params["stiction.static_torque"] < 1.05 * fc:
            m_id = replace_params(m_id, {"stiction.static_torque": 1.3 * fc})
    # Keep whichever start predicts better: the data's own (inverse dynamics) or the model's values.
    own = replace_params(
        m,
        {
            n: m_id.params[n]
            for n in m_id.params
            if n.split(".")[0] in ("delay", "saturation", "ripple", "quantization")
            or n == "stiction.velocity"
        },
    )
    # A third start: the model's base values with the data's values for the added effects.
    # Inverse dynamics can find an effect well (gravity's torque and phase) while biasing a base
    # parameter (b from a closed loop); dropping its effect values then would leave the fit at a
    # degenerate zero (T = 0: no gradient in the phase) from which it never leaves.
    hybrid = replace_params(
        own, {n: v for n, v in m_id.params.items() if n.split(".")[0] not in BASE_EFFECTS}
    )
    id_error = idf.relative_error_percent if idf else math.nan
    starts: list[AxisModel] = []
    for cand in (m_id, own, hybrid):
        if all(cand.params != c.params for c in starts):
            starts.append(cand)
    if not any(n in free for n in HIDDEN_STATE_PARAMS):
        best = min(starts, key=lambda cand: window_cost(meas, est, cand, k))
        cycles: tuple[AxisModel, ...] = ()
        if "ripple.cycles_per_rev" in free and best.has("ripple"):
            cycles = ripple_alternatives(meas, est, best, linear_free)
        rivals = tuple(replace_params(best, {"delay.seconds": v}) for v in rival_delays)
        return StartValues(best, id_error, cycles, rivals)
    # Hidden-state effects are searched by prediction: inverse dynamics has no hidden state, and
    # through a wide dead band it returns nonsense (J ten times too small), on which no width
    # predicts better than none; through a belt it can misjudge J by half, on which a stiff belt
    # predicts better than the true resonance. Judged at the catalogue's default width or
    # frequency, the starts cannot be ranked either: search on each start, keep the best.
    per_start = [_search_hidden_state(meas, est, cand, free, k) for cand in starts]
    # The best of all (on every window); only the best is needed, so the others may stop early.
    best, best_cost = per_start[0][0], math.inf
    for m in (m for found in per_start for m in found):
        cost = window_cost(meas, est, m, k, abandon_above=best_cost)
        if cost < best_cost:
            best, best_cost = m, cost
    # Other basins worth a fit of their own: each start's best two (its base values decide which
    # resonance predicts best before they are refitted), in other basins than the best start.
    others: list[AxisModel] = []
    for found in per_start:
        for m in found[:2]:
            if m is not best and all(_other_basin(m, o) for o in (best, *others)):
                others.append(m)
    rivals = tuple(replace_params(best, {"delay.seconds": v}) for v in rival_delays)
    return StartValues(best, id_error, tuple(others), rivals)


def ripple_alternatives(
    meas: Measurement, est: StateEstimate, model: AxisModel, linear_free: Sequence[str]
) -> tuple[AxisModel, ...]:
    """Starts at other cycle counts for the fitter to try: n ± π/span and n ± 2π/span.

    Over a span of θ a line of sin(nθ) is 2π/span wide in n (3.8 cycles per revolution over
    1.65 rad), and the residual torque the spectrum is taken from carries the smoother's lag and
    the other effects' misfit, so its peak can sit a line width off (37 for 39). The k-step
    prediction has a basin about π/span wide around the true n: starts spaced by that much
    cover the line, each with the amplitude and phase inverse dynamics finds at its n.
    """
    mov = moving_mask(est.omega_rad_s)
    span = float(np.ptp(est.theta_rad[mov])) if np.any(mov) else 0.0
    if span <= 0.0:
        return ()
    n0 = model.params["ripple.cycles_per_rev"]
    step = math.pi / span
    prm = get_param("ripple.cycles_per_rev")
    keep = [*linear_free, "ripple.phase"]
    out = []
    for j in (-2, -1, 1, 2):
        n = n0 + j * step
        if not prm.lower <= n <= prm.upper:
            continue
        cand = replace_params(model, {"ripple.cycles_per_rev": n})
        try:
            idf = fit_inverse_dynamics(meas, est, cand, linear_free, cutoff_hz=_cutoff_hz(cand))
        except ConfigError:
            continue
        out.append(replace_params(cand, {n_: v for n_, v in idf.params.items() if n_ in keep}))
    return tuple(out)


def _other_basin(a: AxisModel, b: AxisModel) -> bool:
    """Whether two starts lie in different basins of the belt frequency (more than 15 % apart,
    or the same frequency from base values more than 15 % apart)."""
    fa, fb = a.params.get("compliance.frequency"), b.params.get("compliance.frequency")
    if fa is None or fb is None:
        return False
    if abs(math.log(fa / fb)) > math.log(1.15):
        return True
    ja, jb = a.params["inertia.J"], b.params["inertia.J"]
    return abs(math.log(ja / jb)) > math.log(1.15)


def _generic_grids(model: AxisModel, free: Sequence[str]) -> list[tuple[str, list[float]]]:
    """(parameter, grid) for every free parameter a generic effect of ``model`` declares a
    search grid for (``Effect.search``), searched one after the other on inverse dynamics."""
    out: list[tuple[str, list[float]]] = []
    for e in model.effects:
        if is_generic(e):
            for short, grid in CATALOGUE[e].search.items():
                if f"{e}.{short}" in free:
                    out.append((f"{e}.{short}", [float(v) for v in grid]))
    return out


def _search_hidden_state(
    meas: Measurement, est: StateEstimate, m_id: AxisModel, free: Sequence[str], k: int
) -> list[AxisModel]:
    """Grid searches by k-step prediction for backlash width and belt frequency/damping: the
    searched model, with the belt's other basins after it (see :func:`search_resonance`)."""
    unit = max(encoder_step_rad(meas.theta_rad), est.noise_rad * math.sqrt(12.0))
    if "backlash.width" in free:
        # From one count up to a tenth of the travel: counts alone (or the noise level, on a log
        # without quantization) can leave the grid far short of a real dead band.
        top = max(unit * BACKLASH_GRID_COUNTS[-1], 0.1 * float(np.ptp(meas.theta_rad)))
        top = min(top, get_param("backlash.width").upper)
        grid = np.geomspace(unit, max(top, 2 * unit), len(BACKLASH_GRID_COUNTS))
        m_id = grid_on_prediction(meas, est, m_id, "backlash.width", [float(w) for w in grid], k)
        # The cost moves in steps as contacts cross sample boundaries, so a gradient barely
        # refines the width: finish the search on a fine grid instead.
        w0 = m_id.params["backlash.width"]
        m_id = grid_on_prediction(meas, est, m_id, "backlash.width", [w0 * f for f in FINE_GRID], k)
    if "compliance.frequency" in free:
        return search_resonance(meas, est, m_id, "compliance.damping" in free, k)
    return [m_id]


def _local_minima(costs: Sequence[float], n: int) -> list[int]:
    """Indices of the ``n`` lowest local minima of a cost profile (ends count), lowest first."""
    c = list(costs)
    idx = [i for i in range(len(c)) if (i == 0 or c[i] <= c[i - 1]) and (i == len(c) - 1 or c[i] <= c[i + 1])]
    return sorted(idx, key=lambda i: c[i])[:n]


def _is_local_minimum(costs: Sequence[float], i: int) -> bool:
    """Whether ``costs[i]`` is a local minimum of the profile (ends count), as :func:`_local_minima`."""
    i %= len(costs)
    return (i == 0 or costs[i] <= costs[i - 1]) and (i == len(costs) - 1 or costs[i] <= costs[i + 1])


def _profile_bound(minima: Sequence[float]) -> float:
    """The cost above which a point of the coarse resonance profile may be abandoned: the
    :data:`RESONANCE_BASINS`-th lowest local minimum confirmed so far (infinite before).

    Exact: only the lowest few local minima are refined, and a point dearer than that many
    confirmed minima can neither be one of them nor, with its cost reported as infinite, make
    a neighbour below the bound a local minimum that it is not (the neighbour is cheaper
    either way). The bound only falls as the scan goes on, so the minima finally chosen are
    below the bound every abandoned point was judged against, and they are the ones the
    unbounded profile gives.
    """
    if len(minima) < RESONANCE_BASINS:
        return math.inf
    return sorted(minima)[RESONANCE_BASINS - 1]


def search_resonance(
    meas: Measurement, est: StateEstimate, model: AxisModel, fit_damping: bool, k: int
) -> list[AxisModel]:
    """Belt frequency (and damping) by k-step prediction: a joint coarse search, then the best
    few basins refined.

    A lightly damped resonance's cost basin is only about ±ζ wide in frequency, and deep only
    near the right damping: at a ratio-1.1 grid with the damping held at one value the true
    basin (ζ = 0.04–0.2) is often stepped over, and a stiff belt far above the loop's bandwidth
    (which predicts like a rigid axis) wins. So the coarse grid takes, at every frequency, the
    best of a few dampings; then each of the :data:`RESONANCE_BASINS` lowest local minima is
    refined (fine frequency grid, damping grid, fine frequency again). Returns the refined
    basins, best first: with base parameters still off (inverse dynamics can misjudge J by half
    through a belt) a stiff belt can predict better than the true resonance until J, b, Fc are
    refitted with it, so the fitter tries each (:class:`StartValues`.alternatives).
    """
    nyq = 0.5 / meas.dt_s
    freqs = [f for f in COMPLIANCE_GRID_HZ if f < 0.8 * nyq]
    if not freqs:
        return [model]
    z0 = model.params["compliance.damping"]
    zetas = COARSE_DAMPING_GRID if fit_damping else (z0,)
    profile: list[tuple[float, AxisModel]] = [(math.inf, model)] * len(freqs)
    # Costs of the profile's confirmed local minima (:func:`_profile_bound`).
    minima: list[float] = []
    j = 0
    # From the stiff end down: a stiff belt predicts like a rigid axis, and it and the belt's
    # own resonance are usually the lowest minima, so the bound is set before the soft end
    # (where a log's costs are highest) is scanned.
    for n in reversed(range(len(freqs))):
        f = freqs[n]
        cands = [replace_params(model, {"compliance.frequency": f, "compliance.damping": z}) for z in zetas]
        # Only the best damping's cost enters the profile: the others may stop early, and
        # trying first the damping that won at the last frequency sets the bar soonest.
        bound = _profile_bound(minima)
        costs = [math.inf] * len(cands)
        for i in (j, *(i for i in range(len(cands)) if i != j)):
            costs[i] = window_cost(meas, est, cands[i], k, GRID_WINDOW_STRIDE, min(*costs, bound))
        j = int(np.argmin(costs))
        profile[n] = (costs[j], cands[j])
        # The point above has both neighbours now (the top one: its one neighbour).
        if n + 1 < len(freqs) and _is_local_minimum([c for c, _ in profile[n : n + 3]], 1):
            minima.append(profile[n + 1][0])
    found: list[tuple[float, AxisModel]] = []
    for i in _local_minima([c for c, _ in profile], RESONANCE_BASINS):
        # Each step's winner carries its cost (same stride) into the next: no re-evaluation.
        c, m = profile[i]
        f0 = m.params["compliance.frequency"]
        # With the damping free a 2 % grid follows once it is set: 4 % steps do here.
        fine = [f0 * f for f in (FINE_GRID[::2] if fit_damping else FINE_GRID)]
        m, c = _grid_with_cost(meas, est, m, "compliance.frequency", fine, k, model_cost=c)
        if fit_damping:
            m, c = _grid_with_cost(
                meas, est, m, "compliance.damping", COMPLIANCE_DAMPING_GRID, k, model_cost=c
            )
            f0 = m.params["compliance.frequency"]
            fine = [f0 * f for f in RESONANCE_FINE_GRID]
            m, c = _grid_with_cost(meas, est, m, "compliance.frequency", fine, k, model_cost=c)
        found.append((c, m))
    return [m for _, m in sorted(found, key=lambda cm: cm[0])]


__all__ = [
    "FINE_GRID",
    "StartValues",
    "grid_on_prediction",
    "find_ripple_cycles",
    "ripple_spectrum",
    "search_start",
    "window_cost",
]
