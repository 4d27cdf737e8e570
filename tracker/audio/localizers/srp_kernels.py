"""SRP-PHAT kernels in numpy: per-window weighted PHAT cross-spectra from shared STFT frames, and
steered responses looked up in GCC tables.

The cross-spectra kernel does, for many windows at once, what
:func:`~tracker.audio.localizers.spectra.snr_weights`,
:func:`~tracker.audio.localizers.spectra.noise_floor`,
:func:`~tracker.audio.localizers.spectra.onset_weights`,
:func:`~tracker.audio.localizers.spectra.pair_cross_spectra`,
:func:`~tracker.audio.localizers.spectra.phat` and
:func:`~tracker.audio.localizers.spectra.snr_ratio_weights` do for one window (the same
formulas, in the same order; the results agree to rounding).

These were numba kernels; importing numba and loading their cached machine code cost every
``tracker audio`` command about 0.45 s, most of what it then spent on a minute of audio. The
sums here run over frames in time order and over pairs in pair order, as the kernels did, so a
window's numbers do not depend on which windows share its batch.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.int64]
Float32Array = NDArray[np.float32]

# The frames' pair products, the windows' sums of them and the GCC tables are float32: their
# relative rounding (1e-7) is far below anything that moves a 0.25° peak, and the gathers, sums
# and the GCC matrix product move and multiply half the bytes.
PRODUCT_DTYPE = np.float32

_TINY = 1e-30
_EPS = 1e-12
_BATCH_VALUES = 1 << 18  # frame-bin-pair products held at once while summing windows


def _low_quantile(values: FloatArray, q: float) -> FloatArray:
    """``np.quantile(values, q, axis=1)`` (linear interpolation, numpy's rounding) of
    ``values`` (n_windows, n_frames, n), from the two order statistics it needs."""
    n = values.shape[1]
    virtual = (n - 1) * q
    below = int(np.floor(virtual))
    gamma = virtual - below
    # Sorting the few frames of each bin is cheaper than partitioning along a middle axis.
    ordered = np.sort(values, axis=1)
    if below + 1 >= n:
        return np.asarray(ordered[:, below])
    a, b = ordered[:, below], ordered[:, below + 1]
    diff = b - a
    if gamma >= 0.5:
        return np.asarray(b - diff * (1.0 - gamma))
    return np.asarray(a + diff * gamma)


def _noise_floor(power: FloatArray, edges: IntArray, interp_index: IntArray, centres: FloatArray,
                 scale: float, quantile: float, bins: IntArray) -> FloatArray:
    """:func:`~tracker.audio.localizers.spectra.noise_floor` of each window at ``bins``.

    ``power`` (n_windows, n_frames, n_freq) are the windows' frames. Each block's floor is an
    order statistic of its frames' and bins' values (exact); the floors are interpolated
    between block centres as ``np.interp`` does. Returns shape (n_windows, n_bins).
    """
    n_windows, n_frames, _ = power.shape
    n_blocks = edges.size - 1
    floors = np.empty((n_windows, n_blocks))
    for b in range(n_blocks):
        values = power[:, :, edges[b] : edges[b + 1]].reshape(n_windows, -1)
        k = int(quantile * (values.shape[1] - 1))
        floors[:, b] = np.partition(values, k, axis=1)[:, k]
    last = n_blocks - 1
    x = bins.astype(float)
    j = interp_index[bins]
    inner = np.clip(j, 0, max(0, last - 1))
    nxt = np.minimum(inner + 1, last)
    span = centres[nxt] - centres[inner]
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (floors[:, nxt] - floors[:, inner]) / np.where(span == 0.0, 1.0, span)
    value = slope * (x - centres[inner]) + floors[:, inner]
    value = np.where(centres[inner] == x, floors[:, inner], value)
    value = np.where(j < 0, floors[:, :1], value)
    value = np.where(j >= last, floors[:, last : last + 1], value)
    return np.asarray(value / scale)


def _frame_weights(power_tiny: FloatArray, rise: FloatArray | None, floor: FloatArray
                   ) -> FloatArray:
    """Each frame's weights at the band's bins: ``rising ** onset_power * clip(1 - floor / P,
    0, 1)`` (:func:`~tracker.audio.localizers.spectra.onset_weights`; 1 without onsets).

    ``power_tiny`` is ``P + 1e-30`` and ``rise`` ``rising ** onset_power`` (None: no onset
    weighting), each (n_windows, n_frames, n_band); ``floor`` (n_windows, n_band). (Where
    ``rising`` is 0 the product is 0: the powers are finite.)
    """
    if rise is None:
        return np.ones_like(power_tiny)
    above = floor[:, None, :] / power_tiny
    np.subtract(1.0, above, out=above)
    np.clip(above, 0.0, 1.0, out=above)
    above *= rise
    return above


def _accumulate(weights: list[FloatArray], cross_re: Float32Array, cross_im: Float32Array,
                rows: IntArray) -> list[tuple[Float32Array, Float32Array]]:
    """``sum_t w[k, t, b] * cross[:, rows[k, t], b]`` in time order for each ``w`` of
    ``weights`` (n_windows, n_frames, n_band) (the frames gathered once for all of them); each
    sum's real and imaginary parts of shape (n_pairs, n_windows, n_band)."""
    n_windows, n_frames = rows.shape
    n_pairs, _, n_band = cross_re.shape
    dtype = cross_re.dtype
    weights = [np.asarray(w, dtype=dtype) for w in weights]
    sums = [(np.empty((n_pairs, n_windows, n_band), dtype=dtype),
             np.empty((n_pairs, n_windows, n_band), dtype=dtype)) for _ in weights]
    step = max(1, _BATCH_VALUES // (n_frames * n_band * n_pairs))
    gathered_buffer = np.empty((n_pairs, min(step, n_windows), n_frames, n_band), dtype=dtype)
    for lo in range(0, n_windows, step):
        r = rows[lo : lo + step]
        # Reused block after block (fresh multi-MB temporaries cost page faults).
        gathered = (gathered_buffer if r.shape[0] == gathered_buffer.shape[1]
                    else np.empty((n_pairs, *r.shape, n_band), dtype=dtype))
        for part, source in enumerate((cross_re, cross_im)):
            np.take(source, r, axis=1, out=gathered)  # (pairs, windows, frames, band)
            for w, acc in zip(weights, sums, strict=True):
                # A sum of products over the frames, in time order (the frames axis is outside
                # the contiguous band axis; tests pin that a window's sum is its own).
                acc[part][:, lo : lo + step] = np.einsum("qktb,ktb->qkb", gathered,
                                                         w[lo : lo + step])
    return sums


def _phat(acc_re: Float32Array, acc_im: Float32Array, weights: FloatArray, phat_beta: float
          ) -> ComplexArray:
    """``C / (|C| + eps) ** beta * weights[b]`` of accumulated cross-spectra (n_pairs,
    n_windows, n_band), returned as (n_windows, n_pairs, n_band) (dividing a complex number
    by a real one is dividing its parts)."""
    scale = np.hypot(acc_re, acc_im) + _EPS
    if phat_beta != 1.0:
        scale = scale * scale if phat_beta == 2.0 else scale**phat_beta
    out = np.empty((acc_re.shape[1], acc_re.shape[0], acc_re.shape[2]), dtype=np.complex128)
    out.real = (acc_re / scale * weights).transpose(1, 0, 2)
    out.imag = (acc_im / scale * weights).transpose(1, 0, 2)
    return out


def weighted_cross_spectra(
    cross_re: Float32Array, cross_im: Float32Array, power: FloatArray, rising: FloatArray,
    rows: IntArray, first_bin: int, edges: IntArray, interp_index: IntArray,
    centres: FloatArray, noise_scale: float, quantile: float, snr_exponent: float, cap: float,
    onset: bool, onset_power: float, phat_beta: float, confidence: bool,
) -> tuple[ComplexArray, ComplexArray]:
    """SRP-PHAT's two weighted PHAT cross-spectra of each window (see ``SrpPhat``).

    Parameters
    ----------
    cross_re, cross_im : ndarray, shape (n_pairs, n_stft, n_band)
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
    rows = np.asarray(rows, dtype=np.int64)
    n_windows, n_t = rows.shape
    n_pairs, _, n_band = cross_re.shape
    bins = np.arange(first_bin, first_bin + n_band)
    use_ratio = snr_exponent >= 0.0
    second = use_ratio and confidence  # the confidence's cross-spectra
    need_low = second or not use_ratio
    frames_power = power[rows]  # (n_windows, n_t, n_freq)
    p = np.ascontiguousarray(frames_power[:, :, first_bin : first_bin + n_band])
    mean = p.sum(axis=1) / n_t  # frames added in time order (an outer axis of a C array)
    low = _low_quantile(p, quantile) if need_low else np.zeros((n_windows, n_band))
    rise = rising[rows]
    # The window's first frame is its own previous one (as in onset_weights).
    rise[:, 0] = np.clip(1.0 - p[:, 0] / (p[:, 0] + _TINY), 0.0, 1.0)
    share = np.clip(1.0 - low / (mean + _TINY), 0.0, 1.0)
    p_tiny = p + _TINY
    rise_pow = None if not onset else (rise * rise if onset_power == 2.0 else rise**onset_power)
    zeros = np.zeros((n_windows, n_pairs, n_band), dtype=np.complex128)
    if not use_ratio:
        [(acc_re, acc_im)] = _accumulate([_frame_weights(p_tiny, rise_pow, low)],
                                         cross_re, cross_im, rows)
        return _phat(acc_re, acc_im, share, phat_beta), zeros
    noise = _noise_floor(frames_power, edges, interp_index, centres, noise_scale, quantile, bins)
    ratio = np.clip(mean / (noise + _TINY) - 1.0, 0.0, cap)
    if snr_exponent == 1.0:
        ratio_weight = ratio
    elif snr_exponent == 2.0:
        ratio_weight = ratio * ratio
    else:
        ratio_weight = ratio**snr_exponent
    weights = [_frame_weights(p_tiny, rise_pow, noise)]
    if second:
        weights.append(_frame_weights(p_tiny, rise_pow, low))
    sums = _accumulate(weights, cross_re, cross_im, rows)
    direction = _phat(*sums[0], ratio_weight, phat_beta)
    if not second:
        return direction, zeros
    return direction, _phat(*sums[1], share, phat_beta)


def store_pair_products(spectra: ComplexArray, first_bin: int, rows: IntArray, first: IntArray,
                        second: IntArray, unit_magnitude: bool, cross_re: Float32Array,
                        cross_im: Float32Array) -> None:
    """Write pair products ``X_i X_j*`` of new STFT frames into a frame store's rows.

    ``spectra`` (n_mics, n_new, n_freq) are the new frames; frame ``k``'s products at the bins
    ``first_bin .. first_bin + n_band - 1`` go to row ``rows[k]`` of ``cross_re``/``cross_im``
    (n_pairs, n_rows, n_band); of ``X / (|X| + 1e-12)`` with ``unit_magnitude``.
    """
    n_band = cross_re.shape[2]
    x = spectra[:, :, first_bin : first_bin + n_band]
    if unit_magnitude:
        x = x / (np.abs(x) + _EPS)
    # In the store's dtype (PRODUCT_DTYPE): the parts rounded once, the products made there.
    re = np.ascontiguousarray(x.real, dtype=cross_re.dtype)
    im = np.ascontiguousarray(x.imag, dtype=cross_re.dtype)
    rows = np.asarray(rows, dtype=np.int64)
    start = int(rows[0]) if rows.size else 0
    consecutive = bool(np.array_equal(rows, np.arange(start, start + rows.size)))
    target = slice(start, start + rows.size) if consecutive else rows  # the usual case: a run
    one, two = np.empty(re.shape[1:], dtype=re.dtype), np.empty(re.shape[1:], dtype=re.dtype)
    for q, (i, j) in enumerate(zip(first.tolist(), second.tolist(), strict=True)):
        # (a + ib)(c - id), its parts written out (numpy's complex product may fuse them).
        np.multiply(re[i], re[j], out=one)
        np.multiply(im[i], im[j], out=two)
        cross_re[q, target] = np.add(one, two, out=one)
        np.multiply(im[i], re[j], out=one)
        np.multiply(re[i], im[j], out=two)
        cross_im[q, target] = np.subtract(one, two, out=one)


def gcc_at_lags(cross: ComplexArray, cosines: Float32Array, minus_sines: Float32Array
                ) -> FloatArray:
    """Upsampled GCCs at a set of lags, from cross-spectra at the band's bins.

    ``g[k, p, l] = sum_b Re(C[k, p, b] exp(i theta[b, l])) / (sum_b |C[k, p, b]| + eps)``
    (``cosines``, ``minus_sines``: ``cos theta``, ``-sin theta``, shape (n_band, n_lags)).
    One matrix product per window (numpy's stacked ``matmul``), so a window's table does not
    depend on the windows beside it; in the dtype of ``cosines`` (float32 from
    :class:`~tracker.audio.localizers.spectra.GccSteering`).

    Returns
    -------
    ndarray, shape (n_windows, n_pairs, n_lags)
    """
    # (n_windows, n_pairs, 2 n_band) @ (2 n_band, n_lags), in the steering's dtype (float32
    # from GccSteering: PRODUCT_DTYPE); the normalisation in float64.
    parts = np.concatenate([cross.real, cross.imag], axis=-1).astype(cosines.dtype)
    steer = np.concatenate([cosines, minus_sines], axis=0)
    total = np.ascontiguousarray(np.hypot(cross.real, cross.imag)).sum(axis=-1, keepdims=True)
    return np.asarray(np.matmul(parts, steer) * (1.0 / (total + _EPS)))


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
    n_windows, n_pairs, n_lags = table.shape
    flat = table.reshape(n_windows, n_pairs * n_lags)
    out = np.zeros((n_windows, columns.shape[0]))
    for p in range(n_pairs):  # pairs added in order, whatever the batch's memory layout
        at = p * n_lags + columns[:, p]
        a = fractions[:, p]
        out += (1.0 - a) * flat[:, at] + a * flat[:, at + 1]
    return np.asarray(out / n_pairs)
