"""GCC-PHAT per pair with sub-sample peak interpolation, then a least-squares direction fit."""

from __future__ import annotations

import numpy as np

from tracker.audio.array import MicArray
from tracker.audio.localizers.base import DirectionEstimate, FloatArray, check_frame
from tracker.audio.localizers.spectra import (
    SpectralSettings,
    band_mask,
    gcc,
    pair_cross_spectra,
    phat,
    snr_weights,
    stft,
)
from tracker.units import SPEED_OF_SOUND_M_PER_S


class GccPhat:
    """Time differences from GCC-PHAT peaks (Knapp & Carter 1976), one per pair.

    Each pair's peak is searched only within its physical lag limit ``|p_i - p_j| / c`` (plus
    one sample of slack for mic placement error), on a GCC upsampled ``settings.upsample``
    times and refined by a parabola through the three best lags. The pair delays are then
    fitted by weighted least squares ``B u = c tau`` (B the baselines), solved in the
    subspace the array spans; the unobservable component is completed toward the front
    (+x) or, for flat arrays, left horizontal.
    """

    name = "gcc_phat"

    def __init__(self, array: MicArray, fs_hz: int, settings: SpectralSettings | None = None
                 ) -> None:
        self.array = array
        self.fs_hz = int(fs_hz)
        self.settings = settings or SpectralSettings()
        self._mask = band_mask(self.fs_hz, self.settings)
        scale = self.fs_hz * self.settings.upsample
        self._max_lag = np.ceil(array.max_lag_s * scale + self.settings.upsample).astype(int)
        self._lag_scale = scale

    def pair_delays(self, frame: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Delay ``tau_ij`` (s) of mic j behind mic i and its GCC peak height per pair.

        Returns
        -------
        delays_s, peaks : ndarray, shape (n_pairs,) each
        """
        spectra = stft(frame, self.settings.nfft)
        cross = phat(pair_cross_spectra(spectra, self.array), self._mask, self.settings.phat_beta)
        g = gcc(cross * snr_weights(spectra)[None, :], self.settings)
        n_lags = g.shape[1]
        delays = np.empty(len(self.array.pairs))
        peaks = np.empty(len(self.array.pairs))
        for p, limit in enumerate(self._max_lag):
            lags = np.arange(-limit, limit + 1)
            values = g[p, lags % n_lags]
            k = int(np.argmax(values))
            offset = 0.0
            if 0 < k < lags.size - 1:
                y0, y1, y2 = values[k - 1], values[k], values[k + 1]
                denom = y0 - 2 * y1 + y2
                offset = 0.5 * (y0 - y2) / denom if denom < 0 else 0.0
            # GCC peaks at lag = t_i - t_j, i.e. minus the delay of j behind i.
            delays[p] = -(lags[k] + offset) / self._lag_scale
            peaks[p] = values[k]
        return delays, peaks

    def locate(self, frame: FloatArray) -> DirectionEstimate:
        """Direction fitted to the per-pair delays of ``frame``, shape (n_mics, n_samples)."""
        frame = check_frame(frame, self.array, self.settings.nfft)
        delays, peaks = self.pair_delays(frame)
        weights = np.clip(peaks, 1e-3, None)
        u = direction_from_delays(self.array, delays, weights)
        elevation = float(np.arcsin(np.clip(u[2], -1, 1))) if self.array.resolves_elevation else None
        return DirectionEstimate(
            azimuth_rad=float(np.arctan2(u[1], u[0])),
            elevation_rad=elevation,
            confidence=float(np.clip(np.mean(peaks), 0.0, 1.0)),
        )


def direction_from_delays(array: MicArray, delays_s: FloatArray, weights: FloatArray
                          ) -> FloatArray:
    """Weighted least-squares unit vector ``u`` with ``B u ≈ c tau``; shape (3,).

    Solved in the row space of the baselines B (shape (n_pairs, 3)); the component the array
    cannot see is filled in to make ``|u| = 1``: along z it is left at 0 (a flat array assumes a
    horizontal source, which does not bias azimuth), otherwise toward +x (the front).
    """
    sqrt_w = np.sqrt(weights)[:, None]
    b = array.baselines_m * sqrt_w
    rhs = SPEED_OF_SOUND_M_PER_S * delays_s * sqrt_w[:, 0]
    _, s, vt = np.linalg.svd(b, full_matrices=True)
    rank = int(np.sum(s > 1e-6 * s[0]))
    u, *_ = np.linalg.lstsq(b, rhs, rcond=1e-6)
    norm = float(np.linalg.norm(u))
    if rank == 3 or norm >= 1.0:
        return np.asarray(u / max(norm, 1e-12))
    null = vt[rank:]  # rows span what the array cannot observe
    z_axis = np.array([0.0, 0.0, 1.0])
    fill_axis = np.array([1.0, 0.0, 0.0])
    if rank == 2 and abs(float(null[0] @ z_axis)) > 0.99:  # only height is unobservable: assume horizontal
        return np.asarray(u / norm)
    fill = null.T @ (null @ fill_axis)
    if np.linalg.norm(fill) < 1e-9:
        fill = null[0]
    fill = fill / np.linalg.norm(fill)
    return np.asarray(u + np.sqrt(1.0 - norm**2) * fill)
