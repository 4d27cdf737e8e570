"""Speech activity: voiced, pitched, speech-band sound clearly above a tracked noise floor."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tracker.audio.filters import (
    butter_lowpass_sos,
    filter_history,
    running_mean,
    running_min,
    sosfilt,
    sosfilt_history,
)
from tracker.errors import ConfigError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class VadSettings:
    """Speech activity detection settings.

    A short frame counts as voiced speech when all of these hold:

    * level at least ``level_above_floor_db`` above the noise floor (the minimum of the
      smoothed level over the trailing ``floor_window_s``): steady fans and hum never pass;
    * harmonicity (normalised autocorrelation peak at a lag in ``pitch_range_hz``) at least
      ``harmonicity_min``: typing, door slams, coughs and other noise bursts are not periodic;
    * at least ``speech_band_min`` of the energy in 200-4000 Hz: low rumbles and door thuds
      are not;
    * the level stands at least ``modulation_min_db`` above its minimum in the half
      ``modulation_window_s`` before the frame (speech comes in syllables; a steady fan or hum
      does not rise);
    * a machine tone is not a voice: when ``causal`` (the default), a frame whose pitch has
      stayed within ``steady_pitch_tolerance`` (relative) over the pitched frames of the
      trailing ``steady_window_s`` is rejected (a voice glides and wobbles; a fan's blade-pass
      whine or mains hum that was just switched on rises in level but holds its pitch), and a
      frame needs ``min_pitched_frames`` pitched frames in that window to be judged at all.
      With ``causal=False`` the level must also dip in the half window *after* the frame
      instead: the older rule, which makes each decision wait ``modulation_window_s / 2``.

    A window is speech when its voiced frames add up to ``min_voiced_s`` (a lone periodic
    click or a cough's voiced instant is too short).
    """

    frame_s: float = 0.032
    hop_s: float = 0.016
    pitch_range_hz: tuple[float, float] = (80.0, 400.0)
    harmonicity_min: float = 0.45
    level_above_floor_db: float = 6.0
    floor_window_s: float = 3.0
    speech_band_min: float = 0.5
    min_voiced_s: float = 0.1
    modulation_min_db: float = 3.0
    modulation_window_s: float = 0.5
    causal: bool = True
    steady_window_s: float = 0.15
    steady_pitch_tolerance: float = 0.01
    min_pitched_frames: int = 3

    def __post_init__(self) -> None:
        if not 0 < self.hop_s <= self.frame_s:
            raise ConfigError(f"VAD hop_s={self.hop_s} must be in (0, frame_s={self.frame_s}]")
        lo, hi = self.pitch_range_hz
        if not 30.0 <= lo < hi <= 1000.0:
            raise ConfigError(f"VAD pitch_range_hz={self.pitch_range_hz} outside 30-1000 Hz")
        if not 0.0 <= self.steady_pitch_tolerance < 0.5:
            raise ConfigError(
                f"VAD steady_pitch_tolerance={self.steady_pitch_tolerance} outside [0, 0.5)")
        if self.min_pitched_frames < 1 or self.steady_window_s < self.hop_s:
            raise ConfigError(
                f"VAD min_pitched_frames={self.min_pitched_frames} must be >= 1 and "
                f"steady_window_s={self.steady_window_s} >= hop_s={self.hop_s}")


@dataclass(frozen=True, slots=True, eq=False)
class VadFeatures:
    """Per-frame features of a mono signal; every array has shape (n_frames,).

    Attributes
    ----------
    times_s : frame centre times.
    level_db : frame energy in dB.
    floor_db : tracked noise floor in dB (causal minimum).
    harmonicity : peak of the window-corrected normalised autocorrelation in the pitch range.
    speech_band : share of energy in 200-4000 Hz.
    modulation_db : rise over the minimum level on the weaker side (before/after) of each frame.
    voiced : the per-frame decision.
    """

    times_s: FloatArray
    level_db: FloatArray
    floor_db: FloatArray
    harmonicity: FloatArray
    speech_band: FloatArray
    modulation_db: FloatArray
    voiced: BoolArray


@dataclass(frozen=True, slots=True, eq=False)
class FrameMeasures:
    """Per-frame measurements the decision is made from; every array has shape (n_frames,):
    level (dB), harmonicity, share of energy in 200-4000 Hz, pitch period (samples)."""

    level_db: FloatArray
    harmonicity: FloatArray
    speech_band: FloatArray
    period: FloatArray

    def __len__(self) -> int:
        return int(self.level_db.size)

    def since(self, k: int) -> FrameMeasures:
        """The measurements from frame ``k`` on."""
        return FrameMeasures(self.level_db[k:], self.harmonicity[k:], self.speech_band[k:],
                             self.period[k:])

    @staticmethod
    def joined(parts: list[FrameMeasures]) -> FrameMeasures:
        """Consecutive measurements as one."""
        return FrameMeasures(*(np.concatenate([getattr(p, name) for p in parts])
                               for name in ("level_db", "harmonicity", "speech_band", "period")))


class SpeechDetector:
    """Frame-level voiced-speech detection over a whole signal (vectorised over frames)."""

    def __init__(self, fs_hz: int, settings: VadSettings | None = None) -> None:
        self.fs_hz = int(fs_hz)
        self.settings = settings or VadSettings()
        s = self.settings
        self.frame = int(round(s.frame_s * fs_hz))
        self.hop = int(round(s.hop_s * fs_hz))
        self.nfft = int(2 ** np.ceil(np.log2(2 * self.frame)))
        self._window = np.hanning(self.frame)
        w_acf = np.fft.irfft(np.abs(np.fft.rfft(self._window, self.nfft)) ** 2)
        self._window_acf = w_acf / w_acf[0]
        self._lags = np.arange(
            int(fs_hz / s.pitch_range_hz[1]), int(np.ceil(fs_hz / s.pitch_range_hz[0])) + 1
        )
        self._sos_low = butter_lowpass_sos(4, min(1000.0, 0.45 * fs_hz), fs_hz)
        freqs = np.fft.rfftfreq(self.nfft, 1.0 / fs_hz)
        in_band = np.flatnonzero((freqs >= 200.0) & (freqs <= 4000.0))
        # A slice, not a mask: summing a masked copy adds in an order that depends on how many
        # frames there are, so a stream's blocks would round differently from the batch.
        self._band = slice(int(in_band[0]), int(in_band[-1]) + 1)

    @property
    def low_pass_sos(self) -> FloatArray:
        """The harmonicity's 1 kHz low-pass, second-order sections (n_sections, 6)."""
        return self._sos_low

    @property
    def lookahead_samples(self) -> int:
        """Samples after a window's end the decision on its last frames depends on.

        Causal: one frame (a frame's time is its centre). Otherwise also the "after" half of
        the modulation test and the 5-frame level smoothing.
        """
        s = self.settings
        if s.causal:
            return self.frame
        half = max(1, int(round(s.modulation_window_s / 2 / s.hop_s)))
        return (half + 4) * self.hop + self.frame

    @property
    def history_samples(self) -> int:
        """Samples before a window the decision depends on (noise floor, smoothing, modulation)."""
        s = self.settings
        floor_frames = max(1, int(round(s.floor_window_s / s.hop_s)))
        half = max(1, int(round(s.modulation_window_s / 2 / s.hop_s)))
        return (floor_frames + half + 8) * self.hop + self.frame

    def features(self, mono: FloatArray) -> VadFeatures:
        """Features of ``mono``, shape (n_samples,); see :class:`VadFeatures`."""
        mono = np.asarray(mono, dtype=float)
        if mono.size < self.frame:
            mono = np.pad(mono, (0, self.frame - mono.size))
        return self.decide(self.measure(mono, sosfilt(self._sos_low, mono)))

    def measure(self, mono: FloatArray, low: FloatArray) -> FrameMeasures:
        """Per-frame measurements of every whole frame of ``mono`` (n_samples,) and of its
        1 kHz low-pass ``low`` (the same samples filtered from the signal's start)."""
        n_frames = 1 + (mono.size - self.frame) // self.hop

        def framed(x: FloatArray) -> FloatArray:  # (n_frames, frame) windowed, no index array
            view = np.lib.stride_tricks.sliding_window_view(x, self.frame)[:: self.hop][:n_frames]
            return np.asarray(view * self._window)

        frames = framed(mono)
        spectrum = np.abs(np.fft.rfft(frames, self.nfft, axis=-1)) ** 2
        total = spectrum.sum(axis=-1) + 1e-20
        speech_band = spectrum[:, self._band].sum(axis=-1) / total
        level_db = 10 * np.log10(np.mean(frames**2, axis=-1) + 1e-20)
        acf = np.fft.irfft(np.abs(np.fft.rfft(framed(low), self.nfft, axis=-1)) ** 2, axis=-1)
        reach = min(self.frame, int(self._lags[-1]) + 2)  # the lags the pitch search reads
        acf = acf[:, :reach] / (acf[:, :1] + 1e-20) / self._window_acf[None, :reach]
        in_range = acf[:, self._lags]
        harmonicity = np.clip(in_range.max(axis=-1), 0.0, 1.0)
        # Pitch period: the shortest lag that is a local peak within 15 % of the highest (the
        # highest alone jumps between one and two periods from frame to frame).
        padded = acf[:, self._lags[0] - 1 : self._lags[-1] + 2]
        local_peak = (in_range >= padded[:, :-2]) & (in_range >= padded[:, 2:])
        near_top = in_range >= 0.85 * in_range.max(axis=-1, keepdims=True)
        period = self._lags[np.argmax(local_peak & near_top, axis=-1)].astype(float)
        return FrameMeasures(level_db, harmonicity, speech_band, period)

    def decide(self, m: FrameMeasures, first_frame: int = 0) -> VadFeatures:
        """The per-frame decision on consecutive frames' measurements (frame ``first_frame``
        of the signal first: it sets the times)."""
        level_db, harmonicity = m.level_db, m.harmonicity
        n_frames = level_db.size
        floor_frames = max(1, int(round(self.settings.floor_window_s / self.settings.hop_s)))
        s = self.settings
        if s.causal:  # trailing 5-frame mean
            smoothed = running_mean(level_db, 5, origin=2)
        else:
            smoothed = running_mean(level_db, 5)
        # Causal minimum over the trailing window: shift the centred filter's origin.
        floor_db = running_min(smoothed, floor_frames, origin=(floor_frames - 1) // 2)
        half = max(1, int(round(s.modulation_window_s / 2 / s.hop_s)))
        # Rise over the lowest level in the half window before (and, not causal, after) the
        # frame: syllables dip, a steady fan or hum does not.
        modulation_db = smoothed - running_min(smoothed, half, origin=(half - 1) // 2)
        pitched = harmonicity >= s.harmonicity_min
        if s.causal:
            pitched &= ~self._steady_pitch(m.period, pitched)
        else:
            dip_after = smoothed - running_min(smoothed, half, origin=-(half // 2))
            modulation_db = np.minimum(modulation_db, dip_after)
        voiced = (
            (level_db >= floor_db + s.level_above_floor_db)
            & pitched
            & (m.speech_band >= s.speech_band_min)
            & (modulation_db >= s.modulation_min_db)
        )
        times = ((np.arange(n_frames) + first_frame) * self.hop + self.frame / 2) / self.fs_hz
        return VadFeatures(times, level_db, floor_db, harmonicity, m.speech_band, modulation_db,
                           voiced)

    def _steady_pitch(self, lag: FloatArray, pitched: BoolArray) -> BoolArray:
        """Frames to reject as a machine tone, or as too early to judge (see VadSettings)."""
        s = self.settings
        n = max(1, int(round(s.steady_window_s / s.hop_s)))
        inf = np.full(n - 1, np.inf)
        hi_lag = np.where(pitched, lag, -np.inf)
        lo_lag = np.where(pitched, lag, np.inf)
        windows_hi = np.lib.stride_tricks.sliding_window_view(np.concatenate([-inf, hi_lag]), n)
        windows_lo = np.lib.stride_tricks.sliding_window_view(np.concatenate([inf, lo_lag]), n)
        count = np.lib.stride_tricks.sliding_window_view(
            np.concatenate([np.zeros(n - 1), pitched.astype(float)]), n).sum(axis=-1)
        spread = (windows_hi.max(axis=-1) - windows_lo.min(axis=-1)) / np.maximum(lag, 1.0)
        too_early = count < s.min_pitched_frames
        return np.asarray(too_early | (spread <= s.steady_pitch_tolerance * 1.0000001), dtype=bool)

    def windows_are_speech(self, features: VadFeatures, start_s: FloatArray, end_s: FloatArray
                           ) -> BoolArray:
        """:meth:`window_is_speech` of many windows ``[start_s, end_s)``; shape of ``start_s``."""
        voiced = np.concatenate([[0], np.cumsum(features.voiced)])
        lo = np.searchsorted(features.times_s, start_s, side="left")
        hi = np.searchsorted(features.times_s, end_s, side="left")
        return np.asarray((voiced[hi] - voiced[lo]) * self.settings.hop_s
                          >= self.settings.min_voiced_s, dtype=bool)

    def window_is_speech(self, features: VadFeatures, start_s: float, end_s: float) -> bool:
        """True when the voiced frames in ``[start_s, end_s)`` add up to ``min_voiced_s``."""
        inside = (features.times_s >= start_s) & (features.times_s < end_s)
        return bool(np.count_nonzero(features.voiced & inside) * self.settings.hop_s
                    >= self.settings.min_voiced_s)


class StreamingSpeechDetector:
    """:meth:`SpeechDetector.features` of a signal that arrives in blocks, measured once.

    Each block is low-passed with the filter's state carried over (the same samples as the
    whole signal's filtering) and every frame it completes is measured once; the decision is
    made over the kept frames' measurements, so it costs no FFT of old audio. The caller
    forgets frames it no longer needs (:meth:`forget_before`; keep the detector's history,
    :attr:`SpeechDetector.history_samples`, before the earliest window still to decide).
    """

    def __init__(self, detector: SpeechDetector) -> None:
        self.detector = detector
        self._history = filter_history(detector.low_pass_sos)
        self._mono = np.zeros(0)  # samples of the frame not yet complete
        self._low = np.zeros(0)
        self._next_frame = 0  # index of the next frame to measure
        self._first_kept = 0  # index of the first kept frame
        self._measures: list[FrameMeasures] = []

    @property
    def frames_measured(self) -> int:
        """Frames measured so far (frame ``k`` covers samples ``k * hop .. k * hop + frame``)."""
        return self._next_frame

    def push(self, mono: FloatArray) -> None:
        """Add the next samples of the mono signal, shape (n_samples,)."""
        d = self.detector
        mono = np.asarray(mono, dtype=float)
        low, self._history = sosfilt_history(d.low_pass_sos, mono, self._history)
        self._mono = np.concatenate([self._mono, mono])
        self._low = np.concatenate([self._low, low])
        if self._mono.size >= d.frame:
            n = 1 + (self._mono.size - d.frame) // d.hop
            self._measures.append(d.measure(self._mono[: (n - 1) * d.hop + d.frame],
                                            self._low[: (n - 1) * d.hop + d.frame]))
            self._mono, self._low = self._mono[n * d.hop :], self._low[n * d.hop :]
            self._next_frame += n

    def forget_before(self, sample: int) -> None:
        """Drop the measurements of the frames that start before ``sample``."""
        kept = FrameMeasures.joined(self._measures) if self._measures else None
        drop = min(max(0, -(-sample // self.detector.hop) - self._first_kept),
                   len(kept) if kept is not None else 0)
        if kept is not None and drop:
            self._measures = [kept.since(drop)]
            self._first_kept += drop

    def features(self) -> VadFeatures:
        """Features of the kept frames (absolute times, from the signal's first sample)."""
        if not self._measures:
            empty = np.zeros(0)
            return VadFeatures(empty, empty, empty, empty, empty, empty, np.zeros(0, dtype=bool))
        return self.detector.decide(FrameMeasures.joined(self._measures), self._first_kept)
