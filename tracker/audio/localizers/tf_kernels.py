"""Compiled time-frequency kernels: smoothed spatial covariance dominance and PHAT vote sums."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

_EPS = 1e-12


@njit(cache=True)
def _reflected_window(n: int, size: int) -> IntArray:
    """Indices averaged at each of ``n`` samples, shape (n, size), reflecting at the edges.

    Same placement as ``scipy.ndimage.uniform_filter`` (mode "reflect", origin 0): sample
    ``i`` averages ``i - size // 2 .. i + size - 1 - size // 2``, with ``d c b a | a b c d``
    edges.
    """
    out = np.empty((n, size), dtype=np.int64)
    for i in range(n):
        for d in range(size):
            index = i - size // 2 + d
            while index < 0 or index >= n:
                index = -index - 1 if index < 0 else 2 * n - index - 1
            out[i, d] = index
    return out


@njit(cache=True)
def _box_smooth(values: ComplexArray, size_t: int, size_f: int) -> ComplexArray:
    """Moving mean over (time, frequency) of shape (n_t, n_f, k), reflecting edges."""
    n_t, n_f, n_k = values.shape
    window_t = _reflected_window(n_t, size_t)
    window_f = _reflected_window(n_f, size_f)
    along_t = np.zeros_like(values)
    for t in range(n_t):
        for d in range(size_t):
            source = values[window_t[t, d]]
            target = along_t[t]
            for f in range(n_f):
                for k in range(n_k):
                    target[f, k] += source[f, k]
    # Along frequency by a running sum: add the sample entering the window, drop the one leaving.
    out = np.empty_like(values)
    scale = 1.0 / (size_t * size_f)
    acc = np.empty(n_k, dtype=np.complex128)
    for t in range(n_t):
        row = along_t[t]
        acc[:] = 0.0
        for d in range(size_f):
            for k in range(n_k):
                acc[k] += row[window_f[0, d], k]
        for k in range(n_k):
            out[t, 0, k] = acc[k] * scale
        for f in range(1, n_f):
            enter, leave = window_f[f, size_f - 1], window_f[f - 1, 0]
            for k in range(n_k):
                acc[k] += row[enter, k] - row[leave, k]
                out[t, f, k] = acc[k] * scale
    return out


@njit(cache=True)
def dominance_share(spectra: ComplexArray, size_t: int, size_f: int, iterations: int,
                    wanted: BoolArray) -> FloatArray:
    """Share of the largest eigenvalue in each locally averaged spatial covariance.

    ``R(t, f) = mean over a size_t x size_f neighbourhood of x x^H`` (x the mic spectra of
    one bin); its largest eigenvalue over its trace is 1 when one plane wave dominates and
    ``1 / n_mics`` in a diffuse field. The eigenvalue comes from ``iterations`` power
    iterations started from the strongest column (exact enough where one wave dominates,
    which is what the test is for).

    Parameters
    ----------
    spectra : ndarray, shape (n_mics, n_frames, n_freq), complex
    size_t, size_f : int
        Neighbourhood in STFT frames and frequency bins.
    iterations : int
    wanted : ndarray of bool, shape (n_frames, n_freq)
        Bins to evaluate; the others are returned as 0.

    Returns
    -------
    ndarray, shape (n_frames, n_freq), values in [0, 1]
    """
    n_m, n_t, n_f = spectra.shape
    n_k = n_m * (n_m + 1) // 2
    upper = np.empty((n_t, n_f, n_k), dtype=np.complex128)
    for t in range(n_t):
        for f in range(n_f):
            k = 0
            for a in range(n_m):
                for b in range(a, n_m):
                    upper[t, f, k] = spectra[a, t, f] * np.conj(spectra[b, t, f])
                    k += 1
    smooth = _box_smooth(upper, size_t, size_f)
    out = np.zeros((n_t, n_f))
    cov = np.empty((n_m, n_m), dtype=np.complex128)
    v = np.empty(n_m, dtype=np.complex128)
    w = np.empty(n_m, dtype=np.complex128)
    for t in range(n_t):
        for f in range(n_f):
            if not wanted[t, f]:
                continue
            k = 0
            for a in range(n_m):
                for b in range(a, n_m):
                    cov[a, b] = smooth[t, f, k]
                    cov[b, a] = np.conj(smooth[t, f, k])
                    k += 1
            out[t, f] = _largest_share(cov, v, w, iterations)
    return out


@njit(cache=True)
def _largest_share(cov: ComplexArray, v: ComplexArray, w: ComplexArray, iterations: int) -> float:
    """Largest eigenvalue over trace of a Hermitian ``cov`` by power iteration (v, w: scratch)."""
    n_m = cov.shape[0]
    trace = 0.0
    best, best_power = 0, -1.0
    for a in range(n_m):
        trace += cov[a, a].real
        if cov[a, a].real > best_power:
            best, best_power = a, cov[a, a].real
    for a in range(n_m):
        v[a] = cov[a, best]
    for _ in range(iterations):
        norm = 0.0
        for a in range(n_m):
            acc = 0j
            for b in range(n_m):
                acc += cov[a, b] * v[b]
            w[a] = acc
            norm += acc.real**2 + acc.imag**2
        norm = np.sqrt(norm) + _EPS
        for a in range(n_m):
            v[a] = w[a] / norm
    largest = 0.0
    for a in range(n_m):
        acc = 0j
        for b in range(n_m):
            acc += cov[a, b] * v[b]
        largest += (np.conj(v[a]) * acc).real
    return float(min(max(largest / (trace + _EPS), 0.0), 1.0))


@njit(cache=True)
def phat_votes(spectra: ComplexArray, weights: FloatArray, first: IntArray, second: IntArray
               ) -> ComplexArray:
    """``sum_t w(t, f) X_i X_j* / |X_i X_j*|`` for each pair (i, j); bins with w = 0 are skipped.

    Parameters
    ----------
    spectra : ndarray, shape (n_mics, n_frames, n_freq), complex
    weights : ndarray, shape (n_frames, n_freq)
    first, second : ndarray of int, shape (n_pairs,)
        Mic indices i and j of each pair.

    Returns
    -------
    ndarray, shape (n_pairs, n_freq), complex
    """
    n_t, n_f = weights.shape
    out = np.zeros((first.size, n_f), dtype=np.complex128)
    for t in range(n_t):
        for f in range(n_f):
            weight = weights[t, f]
            if weight == 0.0:
                continue
            for p in range(first.size):
                c = spectra[first[p], t, f] * np.conj(spectra[second[p], t, f])
                out[p, f] += weight * c / (abs(c) + _EPS)
    return out
