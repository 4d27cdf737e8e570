"""The seed's localizer, reproduced as a baseline: band-pass, running RMS, peak timing, arcsin."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from tracker.audio.array import MicArray
from tracker.audio.localizers.base import DirectionEstimate, FloatArray, check_frame
from tracker.units import SPEED_OF_SOUND_M_PER_S


class SeedRms:
    """The seed report's time-delay method (chapter 5, eq. 5.3), one mic pair per axis.

    1. Band-pass every mic 500-2000 Hz with an elliptic IIR (4th-order low-pass prototype).
    2. Running RMS, reset to zero every 500 ms.
    3. Peak detection: a "peak" is a rising crossing of ``rms[n] - rms[n - D] > threshold``
       (the forced delay ``D`` is 1 ms); times of the k-th peak on each mic are subtracted
       once both mics have counted k peaks.
    4. ``theta = arcsin(c * dt / d)`` per axis (eq. 5.3).

    The seed used a fixed threshold; here it is ``threshold_fraction`` of the window's largest
    RMS step so the method is not disadvantaged by signal level, and the median of the matched
    peak differences is reported instead of only the latest one. The pan pair is the pair most
    aligned with y, the tilt pair the one most aligned with z (when the array has height).
    """

    name = "seed_rms"

    def __init__(
        self,
        array: MicArray,
        fs_hz: int,
        reset_s: float = 0.5,
        step_delay_s: float = 1e-3,
        threshold_fraction: float = 0.3,
    ) -> None:
        self.array = array
        self.fs_hz = int(fs_hz)
        self.reset_samples = max(1, int(round(reset_s * fs_hz)))
        self.step_samples = max(1, int(round(step_delay_s * fs_hz)))
        self.threshold_fraction = threshold_fraction
        high = min(2000.0, 0.45 * fs_hz)
        self._sos = signal.ellip(2, 0.5, 40.0, [500.0, high], btype="bandpass", fs=fs_hz,
                                 output="sos")
        baselines = array.baselines_m
        self._pan_pair = int(np.argmax(np.abs(baselines[:, 1])))
        self._tilt_pair = int(np.argmax(np.abs(baselines[:, 2]))) if array.resolves_elevation else None

    def running_rms(self, frame: FloatArray) -> FloatArray:
        """Band-passed running RMS, reset every ``reset_s``; shape (n_mics, n_samples)."""
        filtered = signal.sosfilt(self._sos, frame, axis=-1)
        n = frame.shape[1]
        block = np.arange(n) // self.reset_samples
        energy = filtered**2
        cumulative = np.cumsum(energy, axis=-1)
        starts = block * self.reset_samples
        before = np.where(starts > 0, cumulative[:, np.maximum(starts - 1, 0)], 0.0)
        count = np.arange(n) - starts + 1
        return np.asarray(np.sqrt((cumulative - before) / count))

    def _peak_times(self, rms: FloatArray) -> list[NDArray[np.intp]]:
        """Sample indices of rising threshold crossings of the RMS step, per mic."""
        d = self.step_samples
        step = np.zeros_like(rms)
        step[:, d:] = rms[:, d:] - rms[:, :-d]
        threshold = self.threshold_fraction * np.max(step) if np.max(step) > 0 else np.inf
        above = step > threshold
        rising = above[:, 1:] & ~above[:, :-1]
        return [np.flatnonzero(r) + 1 for r in rising]

    def _axis_sine(self, rms: FloatArray, pair: int) -> tuple[float, bool]:
        """``c * dt / d`` for one pair (the sine of the angle off broadside) and whether peaks matched."""
        i, j = self.array.pairs[pair]
        times = self._peak_times(rms[[i, j]])
        k = min(times[0].size, times[1].size)
        if k == 0:
            return 0.0, False
        dt_s = float(np.median(times[1][:k] - times[0][:k])) / self.fs_hz  # t_j - t_i
        baseline = self.array.baselines_m[pair]
        return SPEED_OF_SOUND_M_PER_S * dt_s / float(np.linalg.norm(baseline)), True

    def locate(self, frame: FloatArray) -> DirectionEstimate:
        """Pan (and tilt) angle of ``frame``, shape (n_mics, n_samples), by eq. 5.3."""
        frame = check_frame(frame, self.array, 2 * self.step_samples)
        rms = self.running_rms(frame)
        sine, found = self._axis_sine(rms, self._pan_pair)
        baseline = self.array.baselines_m[self._pan_pair]
        sign = np.sign(baseline[1]) or 1.0  # u·b = c dt, with b mostly along y
        azimuth = float(np.arcsin(np.clip(sign * sine, -1.0, 1.0)))
        elevation = None
        if self._tilt_pair is not None:
            tilt_sine, tilt_found = self._axis_sine(rms, self._tilt_pair)
            tilt_sign = np.sign(self.array.baselines_m[self._tilt_pair][2]) or 1.0
            elevation = float(np.arcsin(np.clip(tilt_sign * tilt_sine, -1.0, 1.0)))
            found = found and tilt_found
        return DirectionEstimate(azimuth, elevation, 1.0 if found else 0.0)
