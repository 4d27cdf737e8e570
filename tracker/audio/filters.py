"""Small signal filters in numpy: Butterworth low-pass sections, their filtering, running mean
and minimum, and a Gaussian blur.

The speech detector and the map tracker used ``scipy.signal`` and ``scipy.ndimage`` for these
few lines, and importing those packages took 1-2 s of every ``tracker audio`` command; numba
kernels that replaced them cost 0.45 s of numba start-up. The functions here follow scipy's
definitions (the tests compare them with scipy to 1e-12).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
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


_TAIL = 1e-22  # impulse-response samples below this share of the peak are dropped


@lru_cache(maxsize=16)
def _impulse_response(sections: tuple[tuple[float, ...], ...]) -> FloatArray:
    """The impulse response of stable second-order sections, run until what is left of it
    is below ``_TAIL`` of its peak (the filter then is that FIR filter to rounding)."""
    sos = np.asarray(sections, dtype=float)
    radius = max(float(np.max(np.abs(np.roots(s[3:])))) for s in sos)
    if radius >= 1.0:
        raise ValueError(f"second-order sections with a pole at radius {radius:.6f} are unstable")
    # Repeated poles decay as n^k r^n: a margin of sections * 64 samples covers the powers.
    n = int(np.ceil(np.log(_TAIL) / np.log(max(radius, 1e-3)))) + 64 * sos.shape[0] + 8
    h = np.zeros(n)
    h[0] = 1.0
    for b0, b1, b2, _, a1, a2 in sos:  # direct form I per section on the impulse
        x, y = h, np.zeros(n)
        for i in range(n):
            y[i] = (b0 * x[i] + (b1 * x[i - 1] if i >= 1 else 0.0) + (b2 * x[i - 2] if i >= 2 else 0.0)
                    - (a1 * y[i - 1] if i >= 1 else 0.0) - (a2 * y[i - 2] if i >= 2 else 0.0))
        h = y
    keep = np.flatnonzero(np.abs(h) > _TAIL * np.max(np.abs(h)))
    return np.asarray(h[: int(keep[-1]) + 1])


def _convolve_head(x: FloatArray, h: FloatArray) -> FloatArray:
    """The first ``x.size`` samples of ``x * h`` by FFT overlap-add; shape of ``x``."""
    n, m = x.size, h.size
    nfft = 1 << max(10, int(np.ceil(np.log2(4 * m))))
    if n + m - 1 <= nfft:  # one block: the smallest transform that holds it
        nfft = 1 << int(np.ceil(np.log2(max(n + m - 1, 2))))
    block = nfft - m + 1
    n_blocks = -(-n // block)
    padded = np.zeros(n_blocks * block)
    padded[:n] = x
    spectra = np.fft.rfft(padded.reshape(n_blocks, block), nfft, axis=-1) * np.fft.rfft(h, nfft)
    pieces = np.fft.irfft(spectra, nfft, axis=-1)
    out = pieces[:, :block].copy()
    out[1:, : m - 1] += pieces[:-1, block : block + m - 1]
    return np.asarray(out.ravel()[:n])


def _sections_key(sos: FloatArray) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(v) for v in row) for row in np.asarray(sos, dtype=float))


def sosfilt(sos: FloatArray, x: FloatArray) -> FloatArray:
    """Filter ``x`` (n,) through stable second-order sections from rest (``scipy.signal.sosfilt``
    to rounding: the sections' impulse response, run until it has decayed below 1e-22 of its
    peak, applied by FFT convolution)."""
    return _convolve_head(np.asarray(x, dtype=float), _impulse_response(_sections_key(sos)))


def filter_history(sos: FloatArray) -> FloatArray:
    """The input history :func:`sosfilt_history` starts from (rest): zeros, shape (n_taps - 1,)."""
    return np.zeros(_impulse_response(_sections_key(sos)).size - 1)


def sosfilt_history(sos: FloatArray, x: FloatArray, history: FloatArray
                    ) -> tuple[FloatArray, FloatArray]:
    """:func:`sosfilt` of the next samples ``x`` of a signal whose earlier input ends with
    ``history`` (from :func:`filter_history`, then from the previous call); returns the output
    and the new history (filtering in pieces gives the whole signal's samples)."""
    h = _impulse_response(_sections_key(sos))
    joined = np.concatenate([history, np.asarray(x, dtype=float)])
    y = _convolve_head(joined, h)[history.size :]
    return np.asarray(y), joined[joined.size - (h.size - 1) :].copy()


def _extended(x: FloatArray, size: int, origin: int) -> FloatArray:
    """``x`` extended by its edge values (``mode="nearest"``) for a window of ``size`` whose
    centre is moved by ``origin`` (scipy.ndimage's convention)."""
    before = size // 2 + origin
    after = size - size // 2 - 1 - origin
    return np.concatenate([np.full(before, x[0]), x, np.full(after, x[-1])])


def running_mean(x: FloatArray, size: int, origin: int = 0) -> FloatArray:
    """``scipy.ndimage.uniform_filter1d(x, size, mode="nearest", origin=origin)``.

    Output ``i`` is the mean of ``x[i - size // 2 - origin .. i + (size - 1) // 2 - origin]``
    (edge values repeated), each window summed on its own (scipy keeps a running sum: the
    two agree to rounding); shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    windows = np.lib.stride_tricks.sliding_window_view(_extended(x, size, origin), size)
    return np.asarray(windows.sum(axis=-1) / size)


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
