"""Inverse dynamics of a measured run: smoothed states, filtered regressors and held-out regressions.

The equation of motion ``K·u = J·α + b·ω + Fc·sign ω + Σ τ_effect`` is linear in most
parameters once θ, ω, α are estimated. Every column (and the torque ``K·u``) passes through
the same zero-phase low-pass filter L, so ``L[α] = d²/dt² L[θ]`` holds exactly and the filter
cancels out of the linear terms (the usual IDIM practice; cf. Janot et al., EMPS benchmark).
Samples where the axis is stuck (Karnopp stick: friction is then unknown) are left out, with
a guard band of one filter time constant around them.

Regressions are scored on held-out data: the run is cut into alternating time blocks, fit on
the even blocks and scored on the odd ones and vice versa, so an effect earns its place only
if it predicts data it was not fitted on. Significance uses an effective sample size from the
residual's autocorrelation (residuals are correlated in time).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal, stats

from tracker.errors import DataError
from tracker.workbench.measurements.data import Measurement

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

DEFAULT_CUTOFF_HZ = 50.0
BLOCK_S = 1.0
STUCK_MIN_S = 0.02
ENCODER_MOVING_GAP_S = 0.1  # a longer wait for the next count is a stop, not motion


@dataclass(frozen=True, slots=True)
class Signals:
    """A measured run prepared for inverse dynamics. Full-rate arrays have shape (n,).

    ``theta_rad``, ``omega_rad_s`` and ``alpha_rad_s2`` are the low-passed encoder angle and
    its derivatives; ``stuck`` marks samples where the axis stands still; ``use`` marks the
    decimated samples the regressions use (moving, away from stuck spells and the ends);
    ``fold`` is 0/1 per sample (alternating ``BLOCK_S`` blocks).
    """

    dt_s: float
    cutoff_hz: float
    t_s: FloatArray
    u_v: FloatArray
    theta_raw_rad: FloatArray
    theta_rad: FloatArray
    omega_rad_s: FloatArray
    alpha_rad_s2: FloatArray
    stuck: BoolArray
    use: NDArray[np.int64]
    fold: NDArray[np.int64]
    encoder_step_rad: float
    sos: FloatArray

    def lowpass(self, x: FloatArray) -> FloatArray:
        """The zero-phase low-pass every column goes through. Shape preserved."""
        return np.asarray(signal.sosfiltfilt(self.sos, x, padtype="even"), dtype=float)


def encoder_timing_s(theta_rad: FloatArray, dt_s: float) -> float:
    """How finely the encoder times the response (s): the typical time between count changes
    while moving. A coarse encoder reports a new count only every q/|ω| seconds and anything in
    between is consistent with the data, so an alignment of command and response finer than
    this is not resolved, whatever the sample rate (500 counts per revolution at 0.5 rad/s:
    12.5 ms; an independent generator's clean log of that kind gave a 7.4 ms "delay")."""
    changes = np.flatnonzero(np.diff(theta_rad) != 0.0)
    if changes.size < 2:
        return 0.0
    gaps_s = np.diff(changes) * dt_s
    moving = gaps_s[gaps_s <= ENCODER_MOVING_GAP_S]
    return float(np.median(moving)) if moving.size else 0.0


def encoder_step(theta_rad: FloatArray) -> float:
    """The encoder resolution seen in the data: the typical smallest non-zero step (rad)."""
    d = np.abs(np.diff(theta_rad))
    d = d[d > 1e-12]
    if d.size == 0:
        return 0.0
    small = d[d <= np.percentile(d, 5) * 1.5 + 1e-15]
    return float(np.median(small))


def stuck_mask(theta_rad: FloatArray, omega_rad_s: FloatArray, dt_s: float, step_rad: float) -> BoolArray:
    """Samples where the axis stands still: the encoder holds one value for ≥ STUCK_MIN_S,
    or the smoothed speed is below one encoder step per 50 ms. Shape (n,)."""
    n = theta_rad.size
    change = np.flatnonzero(np.diff(theta_rad) != 0.0)
    edges = np.concatenate(([0], change + 1, [n]))
    lengths = np.diff(edges)
    min_len = max(3, int(round(STUCK_MIN_S / dt_s)))
    run_id = np.repeat(np.arange(lengths.size), lengths)
    stuck = lengths[run_id] >= min_len
    if step_rad > 0:
        stuck |= np.abs(omega_rad_s) < step_rad / 0.05
    return stuck


def prepare_signals(meas: Measurement, cutoff_hz: float | None = None) -> Signals:
    """Smooth the run and pick the samples the regressions may use."""
    dt = meas.dt_s
    fs = 1.0 / dt
    fc = float(min(cutoff_hz or DEFAULT_CUTOFF_HZ, 0.2 * fs))
    sos = signal.butter(4, fc, fs=fs, output="sos")
    th = np.asarray(signal.sosfiltfilt(sos, meas.theta_rad, padtype="even"), dtype=float)
    om = np.gradient(th, dt)
    al = np.gradient(om, dt)
    q = encoder_step(meas.theta_rad)
    stuck = stuck_mask(meas.theta_rad, om, dt, q)
    guard = max(1, int(round(1.0 / fc / dt)))
    near = np.convolve(stuck.astype(float), np.ones(2 * guard + 1), mode="same") > 0
    keep = ~near
    keep[: 3 * guard] = False
    keep[-3 * guard :] = False
    dec = max(1, int(fs // (4.0 * fc)))
    use = np.flatnonzero(keep)
    use = use[use % dec == 0]
    fold = ((meas.t_s - meas.t_s[0]) // BLOCK_S).astype(np.int64) % 2
    if use.size < 50 or np.unique(fold[use]).size < 2:
        raise DataError(_too_little_motion(meas, stuck, keep, use.size, q, guard * dt))
    return Signals(dt, fc, meas.t_s, meas.u_v, meas.theta_rad, th, om, al, stuck, use, fold, q, sos)


def _too_little_motion(
    meas: Measurement, stuck: BoolArray, keep: BoolArray, n_use: int, step_rad: float, guard_s: float
) -> str:
    """Why a log has too few moving samples for inverse dynamics, in its own numbers: how much
    of the run stood still (or crept slower than the encoder can time), the encoder's step and
    count rate, and where the axis did move."""
    dt = meas.dt_s
    duration = float(meas.t_s[-1] - meas.t_s[0]) + dt
    changes = int(np.count_nonzero(np.diff(meas.theta_rad) != 0.0))
    text = f"{meas.source or '<data>'}: only {n_use} usable moving samples"
    if step_rad > 0.0:
        creep = step_rad / STUCK_MIN_S
        text += (
            f": the axis stood still, or moved slower than one encoder step ({step_rad:.3g} rad, "
            f"{2.0 * math.pi / step_rad:.0f} counts/rev) per {1e3 * STUCK_MIN_S:.0f} ms "
            f"({creep:.3g} rad/s), on {100.0 * float(stuck.mean()):.0f} % of the "
            f"{duration:.1f} s run (the reading changed {changes} times), and the inverse "
            f"dynamics uses only samples at least {1e3 * guard_s:.0f} ms from such a stand-still"
        )
        edges = np.flatnonzero(np.diff(np.concatenate(([0], keep.astype(np.int8), [0]))))
        spells = sorted(zip(edges[::2], edges[1::2], strict=True), key=lambda s: s[0] - s[1])[:3]
        if spells:
            where = ", ".join(f"t = {meas.t_s[a]:.2f}–{meas.t_s[b - 1]:.2f} s" for a, b in sorted(spells))
            text += f"; the longest moving spells: {where}"
        text += (
            f". The axis must move faster than {creep:.3g} rad/s for at least a few seconds in all "
            "(faster moves or a finer encoder) to identify anything"
        )
    else:
        text += (
            f": the reading never changes in the {duration:.1f} s run; "
            "the axis must move to identify anything"
        )
    return text


@dataclass(frozen=True, slots=True)
class Regression:
    """A weighted least-squares fit of torque on named columns, full data and held out.

    ``coef`` and ``cov`` are for the fit on all used samples (cov already inflated for the
    effective sample size); ``sse_cv`` sums each fold's squared error when fitted on the other
    fold; ``sse_fold`` holds the two parts; ``residual`` is y − X·coef on the used samples.
    """

    names: tuple[str, ...]
    coef: FloatArray
    cov: FloatArray
    sse: float
    sse_cv: float
    sse_fold: FloatArray
    residual: FloatArray
    n_used: int
    n_eff: float


def effective_samples(residual: FloatArray) -> float:
    """n / (1 + 2 Σ ρ_k), summing the autocorrelation until it first drops below 0.05."""
    r = residual - residual.mean()
    n = r.size
    spec = np.fft.rfft(r, 2 * n)
    ac = np.fft.irfft(spec * np.conj(spec))[: min(n, 2000)]
    if ac[0] <= 0:
        return float(n)
    rho = ac / ac[0]
    below = np.flatnonzero(rho[1:] < 0.05)
    last = int(below[0]) + 1 if below.size else rho.size
    tau = 1.0 + 2.0 * float(np.sum(rho[1:last]))
    return float(max(10.0, n / max(1.0, tau)))


def regress(
    names: tuple[str, ...],
    x: FloatArray,
    y: FloatArray,
    fold: NDArray[np.int64],
    n_eff: float | None = None,
    cv: bool = True,
) -> Regression:
    """Fit y ≈ x·coef (x shape (m, p), y shape (m,)); score held out over the two folds.

    ``cv=False`` skips the held-out fits (grid searches only need the full-data SSE).
    """
    scale = np.sqrt(np.mean(x * x, axis=0))
    scale[scale == 0] = 1.0
    xs = x / scale
    coef_s, *_ = np.linalg.lstsq(xs, y, rcond=None)
    res = y - xs @ coef_s
    sse = float(res @ res)
    sse_fold = np.zeros(2)
    for f in (0, 1) if cv else ():
        tr, te = fold != f, fold == f
        c, *_ = np.linalg.lstsq(xs[tr], y[tr], rcond=None)
        e = y[te] - xs[te] @ c
        sse_fold[f] = float(e @ e)
    m, p = x.shape
    ne = effective_samples(res) if n_eff is None else n_eff
    sigma2 = sse / max(1.0, m - p)
    try:
        cov_s = np.linalg.inv(xs.T @ xs) * sigma2 * (m / ne)
    except np.linalg.LinAlgError:
        cov_s = np.full((p, p), np.inf)
    cov = cov_s / np.outer(scale, scale)
    return Regression(names, coef_s / scale, cov, sse, float(sse_fold.sum()), sse_fold, res, m, ne)


def improvement_p_value(base: Regression, new: Regression, extra_dof: int, n_eff: float) -> float:
    """F-test p-value that ``new`` explains more than ``base`` beyond chance, on ``n_eff``
    effectively independent samples (from the autocorrelation of ``new``'s residual)."""
    p_new = len(new.names)
    d = base.sse - new.sse
    if d <= 0:
        return 1.0
    dof2 = max(1.0, n_eff - p_new)
    f = (d / extra_dof) / (new.sse / dof2)
    return float(stats.f.sf(f, extra_dof, dof2))


def delayed(t_s: FloatArray, x: FloatArray, delay_s: float) -> FloatArray:
    """x(t − delay) by linear interpolation, holding the first value before the start."""
    if delay_s == 0.0:
        return x
    return np.interp(t_s - delay_s, t_s, x)


def circular_fit(c_sin: float, c_cos: float) -> tuple[float, float]:
    """a·sin x + b·cos x = A·sin(x + φ): returns (A, φ)."""
    return math.hypot(c_sin, c_cos), math.atan2(c_cos, c_sin)


__all__ = [
    "Regression",
    "Signals",
    "circular_fit",
    "delayed",
    "effective_samples",
    "encoder_step",
    "improvement_p_value",
    "prepare_signals",
    "regress",
    "stuck_mask",
]
