"""Shared spectral pieces: STFT, PHAT cross-spectra, upsampled GCC and the SRP grid search."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from tracker.audio.array import MicArray, unit_vector
from tracker.audio.localizers.srp_kernels import PRODUCT_DTYPE, gcc_at_lags, table_response

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

_EPS = 1e-12


@dataclass(frozen=True, slots=True)
class SpectralSettings:
    """STFT and band settings shared by the PHAT localizers.

    Attributes
    ----------
    nfft : int
        FFT length in samples (512 = 32 ms at 16 kHz).
    band_hz : tuple of float
        Frequencies kept for localization; voiced speech carries direction cues in
        200 Hz - 7.5 kHz (bins above Nyquist are ignored).
    upsample : int
        GCC interpolation factor: lag resolution is ``1 / (fs * upsample)``.
    phat_beta : float
        Exponent of the PHAT weighting (1 = PHAT); see :func:`phat`.
    """

    nfft: int = 512
    band_hz: tuple[float, float] = (200.0, 7500.0)
    upsample: int = 16
    phat_beta: float = 1.0


def stft(frame: FloatArray, nfft: int) -> ComplexArray:
    """Hann-windowed STFT with 50 % overlap.

    Parameters
    ----------
    frame : ndarray, shape (n_mics, n_samples)

    Returns
    -------
    ndarray, shape (n_mics, n_frames, nfft // 2 + 1)
    """
    hop = nfft // 2
    n_frames = 1 + max(0, (frame.shape[1] - nfft) // hop)
    if frame.shape[1] < nfft:
        frame = np.pad(frame, ((0, 0), (0, nfft - frame.shape[1])))
    starts = np.arange(n_frames) * hop
    index = starts[:, None] + np.arange(nfft)[None, :]
    window = np.hanning(nfft + 1)[:nfft]
    return np.fft.rfft(frame[:, index] * window, axis=-1)


def band_mask(fs_hz: int, settings: SpectralSettings) -> NDArray[np.bool_]:
    """Boolean mask of the rfft bins inside the localization band; shape (nfft // 2 + 1,)."""
    freqs = np.fft.rfftfreq(settings.nfft, 1.0 / fs_hz)
    return (freqs >= settings.band_hz[0]) & (freqs <= settings.band_hz[1])


def pair_cross_spectra(spectra: ComplexArray, array: MicArray, weights: FloatArray | None = None
                       ) -> ComplexArray:
    """Time-summed cross-spectra ``sum_t w(t,f) X_i X_j*`` for every pair.

    Parameters
    ----------
    spectra : ndarray, shape (n_mics, n_frames, n_freq)
    weights : ndarray, shape (n_frames, n_freq), optional

    Returns
    -------
    ndarray, shape (n_pairs, n_freq)
    """
    i, j = np.array(array.pairs).T
    # All pairs at once as one batched product per frequency, (m x t) @ (t x m): much cheaper
    # than forming every pair's (n_frames, n_freq) product.
    weighted = spectra if weights is None else spectra * weights[None]
    covariance = np.transpose(weighted, (2, 0, 1)) @ np.conj(np.transpose(spectra, (2, 1, 0)))
    return np.asarray(covariance[:, i, j].T)


def snr_weights(spectra: ComplexArray, noise_quantile: float = 0.1) -> FloatArray:
    """Per-bin weight ``max(0, 1 - N(f) / S(f))`` from the window's own statistics.

    ``S`` is the mean power over frames and mics, ``N`` a low quantile over frames (the
    stationary noise between syllables). Bins that speech never lifts above the noise, such
    as those between harmonics, get little weight after PHAT has whitened them.

    Parameters
    ----------
    spectra : ndarray, shape (n_mics, n_frames, n_freq)

    Returns
    -------
    ndarray, shape (n_freq,), values in [0, 1]
    """
    power = np.mean(np.abs(spectra) ** 2, axis=0)
    noise = np.quantile(power, noise_quantile, axis=0)
    return np.asarray(np.clip(1.0 - noise / (power.mean(axis=0) + 1e-30), 0.0, 1.0))


def gamma_lower(shape: int, x: float) -> float:
    """Regularized lower incomplete gamma ``P(shape, x)`` of an integer shape >= 1.

    ``P(n, x) = exp(-x) x^n / n! * sum_j x^j / ((n + 1) ... (n + j))`` (the series converges
    for every x > 0 and, unlike ``1 - exp(-x) sum_{k<n} x^k / k!``, has no cancellation in the
    low tail this module asks for).
    """
    if x <= 0.0:
        return 0.0
    term = total = 1.0
    j = 0
    while term > 1e-17 * total:
        j += 1
        term *= x / (shape + j)
        total += term
    return min(1.0, math.exp(shape * math.log(x) - x - math.lgamma(shape + 1)) * total)


@lru_cache(maxsize=32)
def gamma_quantile(quantile: float, n_mics: int) -> float:
    """Quantile of the mean of ``n_mics`` unit-power exponential variables (Gamma(n, 1/n)).

    ``scipy.stats.gamma.ppf(quantile, n_mics, scale=1 / n_mics)`` (the tests compare the two
    to 1e-13), by bisection on :func:`gamma_lower`: scipy.special cost 0.15 s of every
    ``tracker audio`` command's start for one number.
    """
    if not 0.0 < quantile < 1.0 or n_mics < 1:
        raise ValueError(f"gamma_quantile({quantile}, {n_mics}): need 0 < quantile < 1, n_mics >= 1")
    lo, hi = 0.0, 1.0
    while gamma_lower(n_mics, hi) < quantile:
        lo, hi = hi, 2.0 * hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if gamma_lower(n_mics, mid) < quantile:
            lo = mid
        else:
            hi = mid
    return hi / n_mics


def noise_floor(power: FloatArray, n_mics: int, quantile: float = 0.1, block_bins: int = 17
                ) -> FloatArray:
    """Stationary noise power per bin, from one window's low power quantile.

    The ``quantile`` of the mic-averaged power over the frames *and* ``block_bins``
    neighbouring bins (a short window has too few frames for a per-bin floor; noise
    spectra are smooth in frequency while speech is sparse in time and frequency), divided
    by the same quantile of noise alone: a mean over ``n_mics`` independent complex Gaussian
    noise bins of power ``N`` is Gamma(n_mics, N / n_mics) distributed. Block values are
    interpolated linearly between block centres.

    Parameters
    ----------
    power : ndarray, shape (n_frames, n_freq)
        Power averaged over the mics.

    Returns
    -------
    ndarray, shape (n_freq,)
    """
    n_frames, n_freq = power.shape
    edges, centres = noise_blocks(n_freq, block_bins)
    floors = np.empty(centres.size)
    for b in range(centres.size):
        values = power[:, edges[b] : edges[b + 1]].ravel()
        k = int(quantile * (values.size - 1))
        floors[b] = np.partition(values, k)[k]
    scale = gamma_quantile(quantile, n_mics)
    return np.asarray(np.interp(np.arange(n_freq), centres, floors) / scale)


def noise_blocks(n_freq: int, block_bins: int = 17) -> tuple[NDArray[np.int64], FloatArray]:
    """The frequency blocks of :func:`noise_floor`: edges (n_blocks + 1,) and centres (n_blocks,)."""
    n_blocks = max(1, n_freq // block_bins)
    edges = np.linspace(0, n_freq, n_blocks + 1).astype(np.int64)
    return edges, np.asarray(0.5 * (edges[:-1] + edges[1:] - 1), dtype=float)


def snr_ratio_weights(power: FloatArray, noise: FloatArray, exponent: float, cap: float = 30.0
                      ) -> FloatArray:
    """Per-bin weight ``clip(S(f) / N(f) - 1, 0, cap) ** exponent``.

    ``S`` is the window's mean power (speech, its reverberation and noise), ``N`` the noise
    floor (:func:`noise_floor`). ``exponent = 1`` is SNR weighting (near the ML weighting of
    a delay in white noise, Knapp & Carter 1976); smaller exponents keep it from leaning on
    the loud low frequencies, where reverberation is most coherent and the array resolves
    least.

    Parameters
    ----------
    power : ndarray, shape (n_frames, n_freq)
    noise : ndarray, shape (n_freq,)

    Returns
    -------
    ndarray, shape (n_freq,)
    """
    ratio = power.mean(axis=0) / (noise + 1e-30) - 1.0
    return np.asarray(np.clip(ratio, 0.0, cap) ** exponent)


def onset_weights(spectra: ComplexArray, power: float = 2.0, noise_quantile: float = 0.1,
                  noise: FloatArray | None = None) -> FloatArray:
    """Per time-frequency weight: rising power, above the noise.

    ``clip(1 - P(t-1, f) / P(t, f), 0, 1) ** power * clip(1 - N(f) / P(t, f), 0, 1)``:
    bins whose power is rising hold the start of a sound, which reaches the array by the
    direct path before its reflections do (the precedence effect); bins in a decaying tail
    are mostly reverberation. The second factor (``N`` a low quantile of the bin's power over
    the window) keeps noise-only bins, whose power also rises at random, from voting.

    Parameters
    ----------
    spectra : ndarray, shape (n_mics, n_frames, n_freq)

    Returns
    -------
    ndarray, shape (n_frames, n_freq)
    """
    p = np.mean(np.abs(spectra) ** 2, axis=0)
    previous = np.concatenate([p[:1], p[:-1]], axis=0)
    rising = np.clip(1.0 - previous / (p + 1e-30), 0.0, 1.0) ** power
    if noise is None:
        noise = np.quantile(p, noise_quantile, axis=0)
    return np.asarray(rising * np.clip(1.0 - noise[None, :] / (p + 1e-30), 0.0, 1.0))


def phat(cross: ComplexArray, mask: NDArray[np.bool_], beta: float = 1.0) -> ComplexArray:
    """PHAT weighting ``C / |C|**beta`` restricted to ``mask``; shape unchanged.

    ``beta = 1`` is plain PHAT (every bin counts the same); ``beta < 1`` (PHAT-beta) keeps some
    of the spectral shape so bins between speech harmonics, which hold only noise, count less.
    """
    return np.where(mask[None, :], cross / (np.abs(cross) + _EPS) ** beta, 0.0)


def gcc(cross: ComplexArray, settings: SpectralSettings) -> FloatArray:
    """Upsampled generalized cross-correlation of each pair.

    Lag ``k`` (in units of ``1 / (fs * upsample)``) sits at index ``k mod n_lags``;
    normalised so a perfect single plane wave gives a peak of 1.

    Returns
    -------
    ndarray, shape (n_pairs, nfft * upsample)
    """
    n_lags = settings.nfft * settings.upsample
    total = np.sum(np.abs(cross), axis=-1, keepdims=True) + _EPS
    # irfft divides by n_lags and counts each positive bin twice (Hermitian symmetry).
    return np.asarray(np.fft.irfft(cross, n=n_lags, axis=-1) * (n_lags / (2.0 * total)))


def steered_response(cross: ComplexArray, delays_s: FloatArray, fs_hz: int) -> float:
    """Mean over pairs of the normalised GCC at one direction's pair delays, evaluated exactly.

    ``mean_p sum_f Re(C_p(f) exp(-2 pi i f tau_p)) / sum_f |C_p(f)|``: the value :func:`gcc`
    gives at lag ``-tau_p`` (1 for a single plane wave from that direction), without the
    upsampled transform.

    Parameters
    ----------
    cross : ndarray, shape (n_pairs, nfft // 2 + 1)
        Weighted cross-spectra (zero outside the band).
    delays_s : ndarray, shape (n_pairs,)
        Delay of mic j behind mic i for the direction (:meth:`MicArray.delays_s`).
    """
    nfft = 2 * (cross.shape[1] - 1)
    freqs = np.fft.rfftfreq(nfft, 1.0 / fs_hz)
    steer = np.exp(-2j * np.pi * freqs[None, :] * delays_s[:, None])
    total = np.sum(np.abs(cross), axis=1) + _EPS
    return float(np.mean(np.sum((cross * steer).real, axis=1) / total))


def steered_responses(cross_band: ComplexArray, freqs_hz: FloatArray, delays_s: FloatArray
                      ) -> FloatArray:
    """:func:`steered_response` of many windows, from cross-spectra at the band's bins only.

    Parameters
    ----------
    cross_band : ndarray, shape (n_windows, n_pairs, n_band)
    freqs_hz : ndarray, shape (n_band,)
    delays_s : ndarray, shape (n_windows, n_pairs)

    Returns
    -------
    ndarray, shape (n_windows,)
    """
    steer = np.exp(-2j * np.pi * freqs_hz[None, None, :] * delays_s[:, :, None])
    total = np.sum(np.abs(cross_band), axis=2) + _EPS
    return np.asarray(np.mean(np.sum((cross_band * steer).real, axis=2) / total, axis=1))


@dataclass(frozen=True, slots=True)
class GridPeak:
    """The best direction on a grid and its steered response (mean GCC over pairs)."""

    azimuth_rad: float
    elevation_rad: float
    power: float


@dataclass(frozen=True, slots=True, eq=False)
class GccTable:
    """Upsampled GCCs of one or more windows at the lags a direction grid can ask for.

    ``values[..., p, c]`` is pair ``p``'s GCC (as :func:`gcc` gives it) at lag
    ``first_lag + c`` in units of ``1 / (fs * upsample)``; shape (..., n_pairs, n_lags).
    """

    values: FloatArray
    first_lag: int

    def window(self, k: int) -> GccTable:
        """Window ``k`` of a stack of tables."""
        return GccTable(self.values[k], self.first_lag)


def lag_limit(array: MicArray, fs_hz: int, settings: SpectralSettings) -> int:
    """Largest lag (in ``1 / (fs * upsample)``) a plane wave gives any pair, plus interpolation room."""
    return int(np.ceil(float(np.max(array.max_lag_s)) * fs_hz * settings.upsample)) + 2


class GccSteering:
    """Upsampled GCCs at the physical lags only, straight from the band's cross-spectra.

    The GCC of :func:`gcc` at lag ``k`` is ``Re(sum_f C(f) exp(2 pi i f k / n)) / sum_f |C(f)|``
    (``n = nfft * upsample``); only the lags ``-limit..limit`` a direction can give are
    evaluated (:func:`~tracker.audio.localizers.srp_kernels.gcc_at_lags`), instead of an
    ``n``-point inverse FFT per pair.
    """

    def __init__(self, array: MicArray, fs_hz: int, settings: SpectralSettings,
                 band_bins: NDArray[np.int64]) -> None:
        self.limit = lag_limit(array, fs_hz, settings)
        n_lags = settings.nfft * settings.upsample
        lags = np.arange(-self.limit, self.limit + 1)
        phase = 2.0 * np.pi * np.outer(band_bins, lags) / n_lags  # (n_band, n_table)
        self._cosines = np.ascontiguousarray(np.cos(phase), dtype=PRODUCT_DTYPE)
        self._minus_sines = np.ascontiguousarray(-np.sin(phase), dtype=PRODUCT_DTYPE)

    def table(self, cross_band: ComplexArray) -> GccTable:
        """GCC tables of cross-spectra at the band's bins, shape (n_windows, n_pairs, n_band)."""
        values = gcc_at_lags(np.ascontiguousarray(cross_band, dtype=np.complex128),
                             self._cosines, self._minus_sines)
        return GccTable(values, -self.limit)


def gcc_table(g: FloatArray, limit: int) -> GccTable:
    """The lags ``-limit..limit`` of full GCCs ``g``, shape (n_pairs, n_lags), as a table."""
    lags = np.arange(-limit, limit + 1)
    return GccTable(np.asarray(g[:, lags % g.shape[1]]), -limit)


class SrpGrid:
    """Steered response power over a direction grid, by lookup into upsampled GCCs.

    Parameters
    ----------
    array : MicArray
    fs_hz : int
    azimuth_rad, elevation_rad : ndarray, shape (n_grid,)
        The coarse search grid.
    settings : SpectralSettings
    """

    def __init__(
        self,
        array: MicArray,
        fs_hz: int,
        azimuth_rad: FloatArray,
        elevation_rad: FloatArray,
        settings: SpectralSettings,
    ) -> None:
        self.array = array
        self.fs_hz = fs_hz
        self.settings = settings
        self.azimuth_rad = np.asarray(azimuth_rad, dtype=float)
        self.elevation_rad = np.asarray(elevation_rad, dtype=float)
        self._lag_scale = fs_hz * settings.upsample
        self.limit = lag_limit(array, fs_hz, settings)
        self._coarse = self._columns(self._lags(self.azimuth_rad, self.elevation_rad), -self.limit)
        self._az_step = _grid_step(self.azimuth_rad)
        self._el_step = _grid_step(self.elevation_rad)

    def _lags(self, azimuth_rad: FloatArray, elevation_rad: FloatArray) -> FloatArray:
        """Fractional GCC lag of every pair for every direction; shape (..., n_pairs).

        The GCC of pair (i, j) peaks at ``t_i - t_j``, minus the delay of j behind i.
        """
        return -self.array.delays_s(unit_vector(azimuth_rad, elevation_rad)) * self._lag_scale

    @staticmethod
    def _columns(lags: FloatArray, first_lag: int) -> tuple[NDArray[np.int64], FloatArray]:
        """Table column at or below each lag and the fraction towards the next one."""
        low = np.floor(lags)
        return (low - first_lag).astype(np.int64), np.asarray(lags - low)

    def _table(self, g: FloatArray | GccTable) -> GccTable:
        return g if isinstance(g, GccTable) else gcc_table(np.asarray(g), self.limit)

    def response(self, g: FloatArray | GccTable) -> FloatArray:
        """SRP on the coarse grid; shape (n_grid,) for one window's GCCs (full, shape
        (n_pairs, nfft * upsample), or a table), (n_windows, n_grid) for a stack of tables."""
        table = self._table(g)
        values = np.ascontiguousarray(table.values)
        columns, fractions = self._coarse
        if table.first_lag != -self.limit:
            columns = columns - (table.first_lag + self.limit)
        if values.ndim == 2:
            return np.asarray(table_response(values[None], columns, fractions)[0])
        return np.asarray(table_response(values, columns, fractions))

    def peak(self, g: FloatArray | GccTable, refine_step_rad: float = np.deg2rad(0.25)) -> GridPeak:
        """Best coarse grid point of one window, refined on a fine local grid around it."""
        table = self._table(g)
        peaks = self.peaks(GccTable(table.values[None], table.first_lag), refine_step_rad)
        return GridPeak(float(peaks[0][0]), float(peaks[1][0]), float(peaks[2][0]))

    def peaks(self, tables: GccTable, refine_step_rad: float = np.deg2rad(0.25)
              ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Best coarse grid point of each window, refined on a fine local grid around it.

        ``tables.values`` has shape (n_windows, n_pairs, n_lags). Returns azimuth, elevation
        (rad) and steered response (the larger of the coarse and fine peaks), each (n_windows,).
        """
        coarse = self.response(tables)
        best = np.argmax(coarse, axis=1)
        az0, el0 = self.azimuth_rad[best], self.elevation_rad[best]
        span = self._az_step
        offsets = np.arange(-span, span + refine_step_rad / 2, refine_step_rad)
        if self._el_step > 0.0:  # the grid has elevations: refine them too
            el_span = self._el_step
            el_offsets = np.arange(-el_span, el_span + refine_step_rad, 2 * refine_step_rad)
            d_az, d_el = (d.ravel() for d in np.meshgrid(offsets, el_offsets, indexing="ij"))
            az = az0[:, None] + d_az[None, :]
            el = np.clip(el0[:, None] + d_el[None, :], -np.pi / 2, np.pi / 2)
        else:
            az = az0[:, None] + offsets[None, :]
            el = np.broadcast_to(el0[:, None], az.shape)
        columns, fractions = self._columns(self._lags(az, el), tables.first_lag)  # (K, R, P)
        values = tables.values
        windows = np.arange(values.shape[0])[:, None, None]
        pairs = np.arange(values.shape[1])[None, None, :]
        fine = ((1.0 - fractions) * values[windows, pairs, columns]
                + fractions * values[windows, pairs, columns + 1]).mean(axis=2)
        k = np.argmax(fine, axis=1)
        rows = np.arange(values.shape[0])
        power = np.maximum(fine[rows, k], coarse[rows, best])
        return (np.asarray(az[rows, k], dtype=float), np.asarray(el[rows, k], dtype=float),
                np.asarray(power, dtype=float))


def _grid_step(values: FloatArray) -> float:
    """Smallest positive spacing in a grid axis (0 when the axis has one value)."""
    unique = np.unique(np.round(values, 9))
    return float(np.min(np.diff(unique))) if unique.size > 1 else 0.0
