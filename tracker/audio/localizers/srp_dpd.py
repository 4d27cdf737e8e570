"""Direct-path-dominance SRP: SRP-PHAT over only the time-frequency bins one plane wave dominates."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tracker.audio.array import MicArray
from tracker.audio.localizers.base import (
    DirectionEstimate,
    FloatArray,
    check_frame,
    direction_grid,
    wrap_angle,
)
from tracker.audio.localizers.spectra import (
    ComplexArray,
    SpectralSettings,
    SrpGrid,
    band_mask,
    gcc,
    onset_weights,
    stft,
)
from tracker.audio.localizers.tf_kernels import dominance_share, phat_votes


class SrpDpd:
    """SRP-PHAT weighted by a direct-path-dominance test (after Nadiri & Rafaely, 2014).

    For each time-frequency bin the spatial covariance is averaged over a small neighbourhood
    (``smooth_frames`` x ``smooth_bins``); where its largest eigenvalue carries nearly all the
    power the bin is dominated by one plane wave, which early in a speech onset is the direct
    path rather than a reflection. Only the ``keep_fraction`` most dominant bins (among those
    with energy above the window's median) vote, each with PHAT weight, so wall reflections and
    diffuse noise lose their say. Votes are further weighted by how much the bin's power is
    rising (``onset_power``; see :func:`~tracker.audio.localizers.spectra.onset_weights`).
    """

    name = "srp_dpd"

    def __init__(
        self,
        array: MicArray,
        fs_hz: int,
        settings: SpectralSettings | None = None,
        keep_fraction: float = 0.3,
        smooth_frames: int = 3,
        smooth_bins: int = 5,
        azimuth_step_rad: float = np.deg2rad(2.0),
        elevation_step_rad: float = np.deg2rad(5.0),
        azimuth_range_rad: tuple[float, float] | None = None,
        onset_power: float = 1.0,
        power_iterations: int = 4,
    ) -> None:
        self.array = array
        self.fs_hz = int(fs_hz)
        self.settings = settings or SpectralSettings()
        self.keep_fraction = keep_fraction
        self.smooth_frames = smooth_frames
        self.smooth_bins = smooth_bins
        self.onset_power = onset_power
        self.power_iterations = power_iterations
        self._mask = band_mask(self.fs_hz, self.settings)
        az, el = direction_grid(array, azimuth_step_rad, elevation_step_rad, azimuth_range_rad)
        self._grid = SrpGrid(array, self.fs_hz, az, el, self.settings)
        self._first, self._second = (np.array(m, dtype=np.int64) for m in zip(*array.pairs, strict=True))

    def dominance(self, spectra: ComplexArray, wanted: NDArray[np.bool_] | None = None
                  ) -> FloatArray:
        """Share of the largest eigenvalue in each smoothed spatial covariance.

        Parameters
        ----------
        spectra : ndarray, shape (n_mics, n_frames, n_freq)
        wanted : ndarray of bool, shape (n_frames, n_freq), optional
            Bins to evaluate (the rest are 0); all by default.

        Returns
        -------
        ndarray, shape (n_frames, n_freq), values in [0, 1] (1/n_mics in a diffuse field)
        """
        if wanted is None:
            wanted = np.ones(spectra.shape[1:], dtype=bool)
        return dominance_share(np.ascontiguousarray(spectra), self.smooth_frames, self.smooth_bins,
                               self.power_iterations, wanted)

    def locate(self, frame: FloatArray) -> DirectionEstimate:
        """Direction of the strongest direct path in ``frame``, shape (n_mics, n_samples)."""
        frame = check_frame(frame, self.array, self.settings.nfft)
        spectra = stft(frame, self.settings.nfft)[:, :, self._mask]
        power = np.sum(np.abs(spectra) ** 2, axis=0)
        loud = power >= np.median(power)
        dominance = self.dominance(spectra, loud)
        threshold = np.quantile(dominance[loud], 1.0 - self.keep_fraction) if loud.any() else 1.0
        weights = (loud & (dominance >= threshold)).astype(float)
        if self.onset_power > 0:
            weights = weights * onset_weights(spectra, self.onset_power)
        votes = weights.sum(axis=0)  # (n_freq_in_band,)
        n_used = max(int(np.count_nonzero(votes)), 1)
        cross = np.zeros((len(self.array.pairs), self._mask.size), dtype=complex)
        # Bins with more dominant frames weigh more; a coherent plane wave still peaks at 1.
        cross[:, self._mask] = phat_votes(spectra, weights, self._first, self._second) * (
            n_used / max(votes.sum(), 1.0))
        g = gcc(cross, self.settings)
        peak = self._grid.peak(g)
        return DirectionEstimate(
            azimuth_rad=float(wrap_angle(peak.azimuth_rad)),
            elevation_rad=peak.elevation_rad if self.array.sees_elevation else None,
            confidence=float(np.clip(peak.power, 0.0, 1.0)),
        )


__all__ = ["SrpDpd"]
