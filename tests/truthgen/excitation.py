"""Excitation programs: references, feed-forward, PRBS dither, open-loop commands, load disturbance."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfiltfilt

from tests.truthgen.controllers import (
    N_SIG,
    SIG_DITHER,
    SIG_FF,
    SIG_OL_A,
    SIG_OL_C,
    SIG_OL_FLAG,
    SIG_RDOT,
    SIG_REF,
)
from tests.truthgen.presets import GAIN_NM_PER_V, Preset

FloatArray = NDArray[np.float64]


@dataclass(slots=True)
class Program:
    """The per-tick signals of one log and a description of them.

    Attributes
    ----------
    sig : ndarray, shape (N_SIG, n)
        Rows ``SIG_*`` of :mod:`tests.truthgen.controllers`.
    describe : dict
        What the program contains (segment kinds, amplitudes).
    """

    sig: FloatArray
    describe: dict[str, object]


def _min_jerk(x: FloatArray) -> FloatArray:
    """Minimum-jerk profile 0→1 for x in [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def reference(
    rng: np.random.Generator,
    n: int,
    period: float,
    range_rad: float,
    smooth: bool,
    step_speed: float | None = None,
    step_weight: int = 2,
    hold_s: tuple[float, float] = (0.8, 2.5),
    small_share: float = 0.35,
    sweep_top_hz: tuple[float, float] = (1.5, 4.0),
    min_step: float = 0.0,
) -> tuple[FloatArray, list[str]]:
    """A position reference (rad): steps with holds, slow ramps from rest, sine sweeps.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    n : int
        Number of ticks.
    period : float
        Sample period, s.
    range_rad : float
        References stay within ±range_rad, rad.
    smooth : bool
        Steps become minimum-jerk moves and corners are rounded (for feed-forward).
    step_speed : float or None
        When given, (non-smooth) steps are slewed at this speed, rad/s (a trapezoid).
    step_weight : int
        Relative weight of steps against one ramp and one sweep.
    hold_s : tuple of float
        Range of the hold after a step, s.
    small_share : float
        Share of small steps (1–12 % of the range: starts from rest against friction).
    sweep_top_hz : tuple of float
        Range of a sweep's top frequency, Hz (above 4 Hz: faster sweeps, speeds to 4.5 rad/s).
    min_step : float
        Smallest large step, as a share of the range.

    Returns
    -------
    r : ndarray
        Reference at each tick, rad.
    kinds : list of str
        The segments in order.
    """
    t = np.arange(n) * period
    r = np.zeros(n)
    kinds: list[str] = []
    level = 0.0
    cur = int(rng.integers(int(0.3 / period), int(0.8 / period)))  # start at rest
    R = range_rad
    while cur < n:
        kind = str(rng.choice(["step"] * step_weight + ["ramp", "sweep"]))
        kinds.append(kind)
        if kind == "step":
            if rng.random() < small_share:
                delta = float(rng.choice([-1, 1]) * rng.uniform(0.01, 0.12) * R)
            else:
                delta = float(rng.uniform(-R, R) - level)
                delta = float(np.clip(delta, -0.8 * R, 0.8 * R))
                if abs(delta) < min_step * R:  # too small: go the other way, far enough
                    delta = float(-np.sign(level or 1.0) * rng.uniform(min_step, 0.8) * R)
            new = float(np.clip(level + delta, -R, R))
            hold = rng.uniform(*hold_s)
            tr = 0.0
            if smooth:
                tr = max(0.25, 1.875 * abs(new - level) / 2.5)
            elif step_speed is not None:
                tr = abs(new - level) / step_speed
            end = min(n, cur + int((tr + hold) / period))
            tt = t[cur:end] - t[cur]
            if smooth:
                r[cur:end] = level + (new - level) * _min_jerk(tt / tr)
            elif tr > 0.0:
                r[cur:end] = level + (new - level) * np.clip(tt / tr, 0.0, 1.0)
            else:
                r[cur:end] = new
            level = new
        elif kind == "ramp":
            new = float(rng.uniform(-R, R))
            if abs(new - level) < 0.2 * R:
                new = float(np.clip(level + math.copysign(0.4 * R, -level if level != 0 else 1.0), -R, R))
            speed = rng.uniform(0.05, 0.6)
            dur = min(abs(new - level) / speed, 6.0)
            hold = rng.uniform(0.5, 2.0)
            end = min(n, cur + int((dur + hold) / period))
            tt = t[cur:end] - t[cur]
            r[cur:end] = level + (new - level) * np.clip(tt / dur, 0.0, 1.0)
            level = new
        else:
            f0 = rng.uniform(0.2, 0.6)
            f1 = rng.uniform(*sweep_top_hz)
            dur = rng.uniform(4.0, 8.0)
            vmax = rng.uniform(1.5, 3.5) if sweep_top_hz[1] <= 4.0 else rng.uniform(3.0, 4.5)
            amp0 = rng.uniform(0.15, 0.4) * R
            centre = float(np.clip(level, -R + amp0, R - amp0))
            end = min(n, cur + int((dur + 0.6) / period))
            tt = t[cur:end] - t[cur]
            fr = f0 * (f1 / f0) ** np.clip(tt / dur, 0.0, 1.0)
            ph = 2.0 * math.pi * np.cumsum(fr) * period
            amp = np.minimum(amp0, vmax / (2.0 * math.pi * fr))
            taper = np.clip(tt / 0.5, 0.0, 1.0) * np.clip((dur - tt) / 0.5, 0.0, 1.0)
            # Move to the centre first (smoothly), then sweep around it.
            shift = (centre - level) * _min_jerk(tt / 0.5)
            r[cur:end] = level + shift + amp * taper * np.sin(ph)
            level = centre
        cur = end
    if smooth:
        w = max(1, int(0.05 / period))
        kern = np.ones(w) / w
        pad = np.concatenate([np.full(w, r[0]), r, np.full(w, r[-1])])
        r = np.convolve(np.convolve(pad, kern, mode="same"), kern, mode="same")[w:-w]
    return np.clip(r, -R, R), kinds


def feed_forward(r: FloatArray, period: float, p: Preset) -> tuple[FloatArray, FloatArray]:
    """Reference rate (rad/s) and nominal feed-forward voltage (V) of ``J r'' + b r' + Fc·sgn(r')``."""
    rd = np.gradient(r, period)
    rdd = np.gradient(rd, period)
    ff = (p.inertia * rdd + p.viscous * rd + p.coulomb * np.tanh(rd / 0.02)) / GAIN_NM_PER_V
    return rd, ff


def prbs(rng: np.random.Generator, n: int, amplitude: float, hold: int) -> FloatArray:
    """Random ±amplitude bits held ``hold`` ticks each, V."""
    bits = rng.choice([-1.0, 1.0], size=n // hold + 1)
    return amplitude * np.repeat(bits, hold)[:n]


def open_loop_pulses(
    rng: np.random.Generator, n: int, period: float, p: Preset
) -> tuple[FloatArray, FloatArray, list[str]]:
    """Voltage pulses with holds and reversals; flags mark pulse starts (recentring decisions).

    Returns
    -------
    a : ndarray
        Signed pulse program, V.
    flags : ndarray
        1 at the first tick of each pulse, else 0.
    kinds : list of str
        The pattern of each pulse.
    """
    a = np.zeros(n)
    flags = np.zeros(n)
    kinds: list[str] = []
    cur = int(rng.integers(int(0.3 / period), int(0.8 / period)))
    sign = float(rng.choice([-1.0, 1.0]))
    while cur < n:
        if rng.random() < 0.6:
            sign = -sign  # reversal
        v = rng.uniform(1.3, 4.0)
        net = max(GAIN_NM_PER_V * v - p.coulomb, 0.02)
        tau = float(np.clip(rng.uniform(1.5, 3.5) * p.inertia / net, 0.04, 0.5))
        kind = str(rng.choice(["pulse", "pulse", "stair", "hold_bias"]))
        kinds.append(kind)
        k = max(1, int(tau / period))
        end = min(n, cur + k)
        flags[cur] = 1.0
        if kind == "stair":
            mid = min(n, cur + k // 2)
            a[cur:mid] = sign * v
            a[mid:end] = sign * v * rng.uniform(0.5, 0.8)
        else:
            a[cur:end] = sign * v
        hold = rng.uniform(0.2, 1.2)
        hend = min(n, end + int(hold / period))
        if kind == "hold_bias":  # hold a small voltage below break-away
            a[end:hend] = -sign * rng.uniform(0.1, 0.5) * p.coulomb / GAIN_NM_PER_V
        cur = hend
    return a, flags, kinds


def open_loop_chirp(
    rng: np.random.Generator, n: int, period: float, p: Preset
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Log-swept sine command (up and down) with a small switching bias, V.

    The amplitude grows with frequency so the speed stays at a few rad/s; the bias (0.05–0.2 V)
    keeps the axis from sticking at the sweep's slow ends; the operator (the loop) turns its
    sign back when the axis wanders past half the range, and strengthens it (up to 5×) while the
    axis stays beyond the range.

    Returns
    -------
    a : ndarray
        Oscillating command, V.
    c : ndarray
        Bias magnitude, V.
    flags : ndarray
        Decision ticks (every 0.5 s).
    """
    t = np.arange(n) * period
    f0, f1 = rng.uniform(0.5, 1.0), rng.uniform(4.0, 8.0)
    half = rng.uniform(8.0, 15.0)
    x = (t % (2 * half)) / half
    x = np.where(x > 1.0, 2.0 - x, x)
    fr = f0 * (f1 / f0) ** x
    ph = 2.0 * math.pi * np.cumsum(fr) * period
    vamp = rng.uniform(1.0, 2.0)
    amp = 1.3 * p.coulomb / GAIN_NM_PER_V + vamp * p.inertia * 2.0 * math.pi * fr / GAIN_NM_PER_V
    a = np.minimum(amp, 9.0) * np.sin(ph)
    start = int(rng.integers(int(0.3 / period), int(0.8 / period)))
    a[:start] = 0.0
    c = np.full(n, rng.uniform(0.05, 0.2))
    c[:start] = 0.0
    flags = np.zeros(n)
    flags[:: max(1, int(0.5 / period))] = 1.0
    return a, c, flags


def disturbance(rng: np.random.Generator, n: int, period: float, rms: float, bandwidth: float) -> FloatArray:
    """Zero-mean band-limited random torque on the load at the ticks (n+1 values), N·m."""
    if rms <= 0.0:
        return np.zeros(n + 1)
    w = rng.standard_normal(n + 1)
    sos = butter(2, bandwidth, fs=1.0 / period, output="sos")
    d = sosfiltfilt(sos, w)
    d -= d.mean()
    out: FloatArray = rms * d / d.std()
    return out


def empty_program(n: int) -> FloatArray:
    """An all-zero signal matrix, shape (N_SIG, n)."""
    return np.zeros((N_SIG, n))


__all__ = [
    "Program",
    "SIG_DITHER",
    "SIG_FF",
    "SIG_OL_A",
    "SIG_OL_C",
    "SIG_OL_FLAG",
    "SIG_RDOT",
    "SIG_REF",
    "disturbance",
    "empty_program",
    "feed_forward",
    "open_loop_chirp",
    "open_loop_pulses",
    "prbs",
    "reference",
]
