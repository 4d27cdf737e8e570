"""Compiled SRP-PHAT kernels: per-window weighted PHAT cross-spectra from shared STFT frames,
and steered responses looked up in GCC tables.

The cross-spectra kernel does, for many windows at once and without forming per-window arrays,
what :func:`~tracker.audio.localizers.spectra.snr_weights`,
:func:`~tracker.audio.localizers.spectra.noise_floor`,
:func:`~tracker.audio.localizers.spectra.onset_weights`,
:func:`~tracker.audio.localizers.spectra.pair_cross_spectra`,
:func:`~tracker.audio.localizers.spectra.phat` and
:func:`~tracker.audio.localizers.spectra.snr_ratio_weights` do for one window (the same
formulas, in the same order; the results agree to rounding).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.int64]

_TINY = 1e-30
_EPS = 1e-12


@njit(cache=True, error_model="numpy")
def _select(values: FloatArray, n: int, k: int) -> float:
    """The ``k``-th smallest of ``values[:n]`` (0-based); reorders ``values[:n]`` in place so
    that everything after position ``k`` is at least as large (quickselect)."""
    lo, hi = 0, n - 1
    while hi > lo:
        mid = (lo + hi) // 2
        # Median of three as the pivot, moved to hi.
        a, b, c = values[lo], values[mid], values[hi]
        if (a <= b) == (b <= c):
            pivot_at = mid
        elif (b <= a) == (a <= c):
            pivot_at = lo
        else:
            pivot_at = hi
        pivot = values[pivot_at]
        values[pivot_at], values[hi] = values[hi], values[pivot_at]
        store = lo
        for i in range(lo, hi):
            if values[i] < pivot:
                values[store], values[i] = values[i], values[store]
                store += 1
        values[store], values[hi] = values[hi], values[store]
        if store == k:
            return float(values[k])
        if store < k:
            lo = store + 1
        else:
            hi = store - 1
    return float(values[k])


@njit(cache=True, error_model="numpy")
def _quantile(values: FloatArray, n: int, q: float, smallest: FloatArray) -> float:
    """``np.quantile(values[:n], q)`` (linear interpolation, numpy's rounding).

    The two order statistics it needs are the ``k``-th and ``k + 1``-th smallest (``k`` small
    for a low quantile): kept in the sorted buffer ``smallest`` while scanning once.
    """
    virtual = (n - 1) * q
    below = int(np.floor(virtual))
    gamma = virtual - below
    keep = min(below + 2, n)
    size = 0
    for i in range(n):
        v = values[i]
        if size == keep:
            if v >= smallest[size - 1]:
                continue
            size -= 1
        j = size
        while j > 0 and smallest[j - 1] > v:
            smallest[j] = smallest[j - 1]
            j -= 1
        smallest[j] = v
        size += 1
    a = smallest[below]
    if below + 1 >= n:
        return float(a)
    b = smallest[below + 1]
    diff = b - a
    if gamma >= 0.5:
        return float(b - diff * (1.0 - gamma))
    return float(a + diff * gamma)


_SAMPLE = 48  # values sampled to bracket an order statistic


@njit(cache=True, error_model="numpy")
def _kth_smallest(values: FloatArray, n: int, k: int, sample: FloatArray, buffer: FloatArray
                  ) -> float:
    """The ``k``-th smallest of ``values[:n]`` (0-based), exactly; ``values`` is reordered.

    Brackets it between two values of an evenly spaced sample of ``sample.size`` values; one
    pass counts the values below the bracket and collects those inside (few, for a low
    quantile), and the selection runs on those only. Falls back to a quickselect over all the
    values when the bracket misses. ``buffer`` holds at least ``n`` values.
    """
    n_sample = sample.size
    if n < 8 * n_sample:
        return _select(values, n, k)
    for i in range(n_sample):
        sample[i] = values[(i * n) // n_sample]
    sample.sort()
    centre = (k * n_sample) // n
    lo = sample[centre - 4] if centre >= 4 else -np.inf
    hi = sample[centre + 5] if centre + 5 < n_sample else np.inf
    below = 0
    inside = 0
    for i in range(n):
        v = values[i]
        if v < lo:
            below += 1
        elif v <= hi:
            buffer[inside] = v
            inside += 1
    if below <= k < below + inside:
        return _select(buffer, inside, k - below)
    return _select(values, n, k)


@njit(cache=True, error_model="numpy")
def _noise_floor(power: FloatArray, rows: IntArray, edges: IntArray, interp_index: IntArray,
                 centres: FloatArray, scale: float, quantile: float, scratch: FloatArray,
                 buffer: FloatArray, out: FloatArray) -> None:
    """:func:`~tracker.audio.localizers.spectra.noise_floor` of the frames ``rows`` into ``out``."""
    n_t = rows.size
    n_blocks = edges.size - 1
    floors = np.empty(n_blocks)
    sample = np.empty(_SAMPLE)
    for b in range(n_blocks):
        n = 0
        for t in range(n_t):
            row = power[rows[t]]
            for f in range(edges[b], edges[b + 1]):
                scratch[n] = row[f]
                n += 1
        floors[b] = _kth_smallest(scratch, n, int(quantile * (n - 1)), sample, buffer)
    last = n_blocks - 1
    for f in range(out.size):
        x = float(f)
        j = interp_index[f]
        if j < 0:
            value = floors[0]
        elif j >= last:
            value = floors[last]
        elif centres[j] == x:
            value = floors[j]
        else:
            slope = (floors[j + 1] - floors[j]) / (centres[j + 1] - centres[j])
            value = slope * (x - centres[j]) + floors[j]
        out[f] = value / scale


@njit(cache=True, error_model="numpy")
def _power(value: float, exponent: float) -> float:
    """``value ** exponent`` with the common exponents 1 and 2 exact and cheap."""
    if exponent == 1.0:
        return value
    if exponent == 2.0:
        return value * value
    return float(value**exponent)


@njit(cache=True, error_model="numpy")
def _frame_weights(p_cur: FloatArray, rising: FloatArray, floor: FloatArray, onset: bool,
                   onset_power: float, out: FloatArray) -> None:
    """One frame's weights at the band's bins: ``rising ** onset_power * clip(1 - floor / P,
    0, 1)`` (:func:`~tracker.audio.localizers.spectra.onset_weights`; 1 without ``onset``)."""
    if not onset:
        out[:] = 1.0
        return
    for b in range(out.size):
        rise = rising[b]
        if rise == 0.0:  # falling power (about half the bins): no vote, no division
            out[b] = 0.0
            continue
        rise = rise * rise if onset_power == 2.0 else rise**onset_power
        out[b] = rise * min(max(1.0 - floor[b] / (p_cur[b] + _TINY), 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def _accumulate(weights: FloatArray, c_re: FloatArray, c_im: FloatArray, acc_re: FloatArray,
                acc_im: FloatArray) -> None:
    """``acc += weights[b] * c[b, :]`` over the band's bins (zero weights skipped)."""
    n_pairs = c_re.shape[1]
    for b in range(weights.size):
        weight = weights[b]
        if weight != 0.0:
            for q in range(n_pairs):
                acc_re[b, q] += weight * c_re[b, q]
                acc_im[b, q] += weight * c_im[b, q]


@njit(cache=True, error_model="numpy")
def _phat(acc_re: FloatArray, acc_im: FloatArray, weights: FloatArray, phat_beta: float,
          out: ComplexArray) -> None:
    """``out[q, b] = C / (|C| + eps) ** beta * weights[b]`` of the accumulated cross-spectra
    (dividing a complex number by a real one is dividing its parts, as numpy does)."""
    n_band, n_pairs = acc_re.shape
    for b in range(n_band):
        weight = weights[b]
        for q in range(n_pairs):
            re, im = acc_re[b, q], acc_im[b, q]
            scale = _power(math.hypot(re, im) + _EPS, phat_beta)
            out[q, b] = complex(re / scale * weight, im / scale * weight)


@njit(cache=True, error_model="numpy")
def weighted_cross_spectra(
    cross_re: FloatArray, cross_im: FloatArray, power: FloatArray, rising: FloatArray,
    rows: IntArray, first_bin: int, edges: IntArray, interp_index: IntArray,
    centres: FloatArray, noise_scale: float, quantile: float, snr_exponent: float, cap: float, onset: bool,
    onset_power: float, phat_beta: float, confidence: bool,
) -> tuple[ComplexArray, ComplexArray]:
    """SRP-PHAT's two weighted PHAT cross-spectra of each window (see ``SrpPhat``).

    Parameters
    ----------
    cross_re, cross_im : ndarray, shape (n_stft, n_band, n_pairs)
        Every STFT frame's pair products ``X_i X_j*`` at the band's bins.
    power : ndarray, shape (n_stft, n_freq)
        Every frame's power averaged over the mics, at all bins.
    rising : ndarray, shape (n_stft, n_band)
        Every frame's power rise over the frame one hop earlier
        (:class:`~tracker.audio.localizers.frames.StftFrames`); read for a window's frames
        after its first.
    rows : ndarray of int, shape (n_windows, n_frames)
        Each window's frames (rows of the arrays above), consecutive in time.
    first_bin : int
        The band's first bin (the band is ``first_bin .. first_bin + n_band - 1``).
    edges, interp_index, centres, noise_scale
        The noise floor's frequency blocks, each bin's block interval and the Gamma quantile
        (:func:`~tracker.audio.localizers.spectra.noise_floor`).
    quantile : float
        Low power quantile taken as the noise (0.1).
    snr_exponent : float
        < 0: no noise floor (the ``1 - N/S`` share weights the direction, no second output).
    onset : bool
        Weight bins by rising power (:func:`~tracker.audio.localizers.spectra.onset_weights`).
    confidence : bool
        Also the confidence's cross-spectra (only they need the per-bin low quantile, when
        ``snr_exponent >= 0``); False leaves them zero.

    Returns
    -------
    direction, confidence : ndarray, shape (n_windows, n_pairs, n_band), complex
        The direction's cross-spectra (onsets above the noise floor, SNR-ratio weights) and
        the confidence's (onsets above the low quantile, ``1 - N/S`` weights; zeros when
        ``snr_exponent < 0`` or not ``confidence``).
    """
    n_windows, n_t = rows.shape
    n_band, n_pairs = cross_re.shape[1], cross_re.shape[2]
    n_freq = power.shape[1]
    band = slice(first_bin, first_bin + n_band)
    use_ratio = snr_exponent >= 0.0
    second = use_ratio and confidence  # the confidence's cross-spectra
    need_low = second or not use_ratio
    out0 = np.zeros((n_windows, n_pairs, n_band), dtype=np.complex128)
    out1 = np.zeros((n_windows, n_pairs, n_band), dtype=np.complex128)
    widest = 0
    for b in range(edges.size - 1):
        widest = max(widest, edges[b + 1] - edges[b])
    scratch = np.empty(max(n_t * widest, n_t))
    buffer = np.empty(scratch.size)
    smallest = np.empty(n_t + 2)
    low = np.zeros(n_band)
    mean = np.empty(n_band)
    noise = np.zeros(n_freq)
    weight0 = np.empty(n_band)
    weight1 = np.empty(n_band)
    w0 = np.empty(n_band)
    w1 = np.empty(n_band)
    first_rise = np.empty(n_band)
    acc0_re = np.empty((n_band, n_pairs))
    acc0_im = np.empty((n_band, n_pairs))
    acc1_re = np.empty((n_band, n_pairs))
    acc1_im = np.empty((n_band, n_pairs))
    for k in range(n_windows):
        r = rows[k]
        for b in range(n_band):
            f = first_bin + b
            total = 0.0
            for t in range(n_t):
                value = power[r[t], f]
                scratch[t] = value
                total += value
            mean[b] = total / n_t
            if need_low:
                low[b] = _quantile(scratch, n_t, quantile, smallest)
        if use_ratio:
            _noise_floor(power, r, edges, interp_index, centres, noise_scale, quantile,
                         scratch, buffer, noise)
        noise_band = noise[band]
        acc0_re[:] = 0.0
        acc0_im[:] = 0.0
        acc1_re[:] = 0.0
        acc1_im[:] = 0.0
        for t in range(n_t):
            row = r[t]
            p_cur = power[row, band]
            if t > 0:
                rise = rising[row]
            else:  # the window's first frame is its own previous one (as in onset_weights)
                for b in range(n_band):
                    first_rise[b] = min(max(1.0 - p_cur[b] / (p_cur[b] + _TINY), 0.0), 1.0)
                rise = first_rise
            if use_ratio:
                _frame_weights(p_cur, rise, noise_band, onset, onset_power, w0)
                _accumulate(w0, cross_re[row], cross_im[row], acc0_re, acc0_im)
            if need_low:
                _frame_weights(p_cur, rise, low, onset, onset_power, w1)
                if second:
                    _accumulate(w1, cross_re[row], cross_im[row], acc1_re, acc1_im)
                else:
                    _accumulate(w1, cross_re[row], cross_im[row], acc0_re, acc0_im)
        for b in range(n_band):
            share = min(max(1.0 - low[b] / (mean[b] + _TINY), 0.0), 1.0)
            weight1[b] = share
            if use_ratio:
                weight0[b] = _power(min(max(mean[b] / (noise_band[b] + _TINY) - 1.0, 0.0), cap),
                                    snr_exponent)
            else:
                weight0[b] = share
        _phat(acc0_re, acc0_im, weight0, phat_beta, out0[k])
        if second:
            _phat(acc1_re, acc1_im, weight1, phat_beta, out1[k])
    return out0, out1


@njit(cache=True, error_model="numpy")
def store_pair_products(spectra: ComplexArray, first_bin: int, rows: IntArray, first: IntArray,
                        second: IntArray, unit_magnitude: bool, cross_re: FloatArray,
                        cross_im: FloatArray) -> None:
    """Write pair products ``X_i X_j*`` of new STFT frames into a frame store's rows.

    ``spectra`` (n_mics, n_new, n_freq) are the new frames; frame ``k``'s products at the bins
    ``first_bin .. first_bin + n_band - 1`` go to row ``rows[k]`` of ``cross_re``/``cross_im``
    (n_rows, n_band, n_pairs); of ``X / (|X| + 1e-12)`` with ``unit_magnitude``.
    """
    n_mics, n_new = spectra.shape[0], spectra.shape[1]
    n_band = cross_re.shape[1]
    x = np.empty(n_mics, dtype=np.complex128)
    for k in range(n_new):
        row = rows[k]
        for b in range(n_band):
            for m in range(n_mics):
                value = spectra[m, k, first_bin + b]
                x[m] = value / (abs(value) + _EPS) if unit_magnitude else value
            for q in range(first.size):
                c = x[first[q]] * np.conj(x[second[q]])
                cross_re[row, b, q] = c.real
                cross_im[row, b, q] = c.imag


@njit(cache=True, error_model="numpy")
def gcc_at_lags(cross: ComplexArray, cosines: FloatArray, minus_sines: FloatArray) -> FloatArray:
    """Upsampled GCCs at a set of lags, from cross-spectra at the band's bins.

    ``g[k, p, l] = sum_b Re(C[k, p, b] exp(i theta[b, l])) / (sum_b |C[k, p, b]| + eps)``
    (``cosines``, ``minus_sines``: ``cos theta``, ``-sin theta``, shape (n_band, n_lags)).
    Compiled, single-threaded and the same for a window whatever its batch (a BLAS product
    may start threads and round a batch differently).

    Returns
    -------
    ndarray, shape (n_windows, n_pairs, n_lags)
    """
    n_windows, n_pairs, n_band = cross.shape
    n_lags = cosines.shape[1]
    out = np.zeros((n_windows, n_pairs, n_lags))
    for k in range(n_windows):
        for p in range(n_pairs):
            g = out[k, p]
            total = 0.0
            for b in range(n_band):
                c = cross[k, p, b]
                re, im = c.real, c.imag
                total += math.hypot(re, im)
                cos_b = cosines[b]
                sin_b = minus_sines[b]
                for lag in range(n_lags):
                    g[lag] += re * cos_b[lag] + im * sin_b[lag]
            scale = 1.0 / (total + _EPS)
            for lag in range(n_lags):
                g[lag] *= scale
    return out


@njit(cache=True, error_model="numpy")
def table_response(table: FloatArray, columns: IntArray, fractions: FloatArray) -> FloatArray:
    """Mean over pairs of the linearly interpolated GCC tables at each direction's lags.

    Parameters
    ----------
    table : ndarray, shape (n_windows, n_pairs, n_lags)
    columns : ndarray of int, shape (n_grid, n_pairs)
        Column of the lag at or below each direction's lag (the next one is ``+ 1``).
    fractions : ndarray, shape (n_grid, n_pairs)
        Where the lag falls between the two columns.

    Returns
    -------
    ndarray, shape (n_windows, n_grid)
    """
    n_windows, n_pairs, _ = table.shape
    n_grid = columns.shape[0]
    out = np.empty((n_windows, n_grid))
    for k in range(n_windows):
        g = table[k]
        for d in range(n_grid):
            total = 0.0
            for p in range(n_pairs):
                c = columns[d, p]
                a = fractions[d, p]
                total += (1.0 - a) * g[p, c] + a * g[p, c + 1]
            out[k, d] = total / n_pairs
    return out
