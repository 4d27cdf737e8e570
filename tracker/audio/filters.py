"""Small signal filters without scipy: Butterworth low-pass sections, their filtering, running
mean and minimum, and a Gaussian blur.

The speech detector and the map tracker used ``scipy.signal`` and ``scipy.ndimage`` for these
few lines, and importing those packages took 1-2 s of every ``tracker audio`` command. The
functions here follow scipy's definitions (same formulas, same operation order where that sets
the rounding; the tests compare them with scipy to 1e-12).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def butter_lowpass_sos(order: int, cutoff_hz: float, fs_hz: float) -> FloatArray:
    """Digital Butterworth low-pass as second-order sections (``scipy.signal.butter(order,
    cutoff_hz, "lowpass", fs=fs_hz, output="sos")``), for an even ``order``.

    The analog prototype's poles are scaled to the pre-warped cut-off and mapped by the
    bilinear transform; the zeros sit at z = -1. Sections are ordered with the poles closest
    to the unit circle last; the gain goes into the first section.

    Returns
    -------
    ndarray, shape (order // 2, 6): ``[b0, b1, b2, 1, a1, a2]`` per section.
    """
    if order < 2 or order % 2:
        raise ValueError(f"order={order}: an even order >= 2 is supported")
    if not 0.0 < cutoff_hz < fs_hz / 2:
        raise ValueError(f"cutoff_hz={cutoff_hz} must be within (0, fs_hz / 2)")
    fs = 2.0  # scipy designs at a normalised rate of 2
    warped = 2.0 * fs * np.tan(np.pi * (2.0 * cutoff_hz / fs_hz) / fs)
    analog = -np.exp(1j * np.pi * np.arange(-order + 1, order, 2) / (2 * order)) * warped
    gain = warped**order
    fs2 = 2.0 * fs
    poles = (fs2 + analog) / (fs2 - analog)
    gain = float(np.real(gain * (1.0 / np.prod(fs2 - analog))))
    upper = poles[poles.imag > 0]
    upper = upper[np.argsort(np.abs(1.0 - np.abs(upper)))[::-1]]  # the worst (nearest) last
    sos = np.zeros((order // 2, 6))
    for i, pole in enumerate(upper):
        sos[i, :3] = np.poly([-1.0, -1.0])
        sos[i, 3:] = np.poly([pole, np.conj(pole)]).real
    sos[0, :3] *= gain
    return sos


def sosfilt(sos: FloatArray, x: FloatArray) -> FloatArray:
    """Filter ``x`` (n,) through second-order sections from rest (``scipy.signal.sosfilt``:
    transposed direct form II, the same operations)."""
    return sosfilt_state(sos, np.asarray(x, dtype=float), np.zeros((sos.shape[0], 2)))[0]


@njit(cache=True, error_model="numpy")
def sosfilt_state(sos: FloatArray, x: FloatArray, state: FloatArray
                  ) -> tuple[FloatArray, FloatArray]:
    """:func:`sosfilt` continuing from ``state`` (n_sections, 2); returns the output and the
    state after the last sample (filtering in pieces gives the whole signal's samples)."""
    n_sections = sos.shape[0]
    state = state.copy()
    y = np.empty_like(x)
    for n in range(x.size):
        value = x[n]
        for s in range(n_sections):
            out = sos[s, 0] * value + state[s, 0]
            state[s, 0] = sos[s, 1] * value - sos[s, 4] * out + state[s, 1]
            state[s, 1] = sos[s, 2] * value - sos[s, 5] * out
            value = out
        y[n] = value
    return y, state


def _extended(x: FloatArray, size: int, origin: int) -> FloatArray:
    """``x`` extended by its edge values (``mode="nearest"``) for a window of ``size`` whose
    centre is moved by ``origin`` (scipy.ndimage's convention)."""
    before = size // 2 + origin
    after = size - size // 2 - 1 - origin
    return np.concatenate([np.full(before, x[0]), x, np.full(after, x[-1])])


@njit(cache=True, error_model="numpy")
def _running_mean(extended: FloatArray, size: int, n: int) -> FloatArray:
    out = np.empty(n)
    total = 0.0
    for i in range(size):
        total += extended[i]
    out[0] = total / size
    for i in range(1, n):
        total += extended[i + size - 1] - extended[i - 1]
        out[i] = total / size
    return out


def running_mean(x: FloatArray, size: int, origin: int = 0) -> FloatArray:
    """``scipy.ndimage.uniform_filter1d(x, size, mode="nearest", origin=origin)``.

    Output ``i`` is the mean of ``x[i - size // 2 - origin .. i + (size - 1) // 2 - origin]``
    (edge values repeated), from a running sum as scipy keeps it; shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    return np.asarray(_running_mean(_extended(x, size, origin), size, x.size))


def running_min(x: FloatArray, size: int, origin: int = 0) -> FloatArray:
    """``scipy.ndimage.minimum_filter1d(x, size, mode="nearest", origin=origin)``; shape of x."""
    x = np.asarray(x, dtype=float)
    windows = np.lib.stride_tricks.sliding_window_view(_extended(x, size, origin), size)
    return np.asarray(windows.min(axis=-1))


def gaussian_blur(values: FloatArray, sigma: float, wrap: bool = False) -> FloatArray:
    """``scipy.ndimage.gaussian_filter1d(values, sigma, axis=-1, mode="nearest")`` (``mode="wrap"``
    with ``wrap``: the last axis is a circle).

    The kernel reaches ``int(4 sigma + 0.5)`` samples either side and sums to one; shape of
    ``values`` (..., n).
    """
    radius = int(4.0 * sigma + 0.5)
    x = np.arange(-radius, radius + 1)
    weights = np.exp(-0.5 / sigma**2 * x**2)
    weights = weights / weights.sum()
    values = np.asarray(values, dtype=float)
    if wrap:
        turns = -(-radius // values.shape[-1])  # whole turns needed either side
        circle = np.concatenate([values] * (2 * turns + 1), axis=-1)
        start = turns * values.shape[-1] - radius
        padded = circle[..., start : start + values.shape[-1] + 2 * radius]
    else:
        padded = np.concatenate([np.repeat(values[..., :1], radius, axis=-1), values,
                                 np.repeat(values[..., -1:], radius, axis=-1)], axis=-1)
    n = values.shape[-1]
    out = values * weights[radius]
    for j in range(radius, 0, -1):  # symmetric pairs, farthest first, as scipy sums them
        left = padded[..., radius - j : radius - j + n]
        right = padded[..., radius + j : radius + j + n]
        out = out + (left + right) * weights[radius - j]
    return np.asarray(out)
