"""Recording in, per-window estimates and the tracked camera direction out (offline or streamed)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.audio.array import MicArray
from tracker.audio.localizers import DEFAULT_LOCALIZER, Localizer, make_localizer
from tracker.audio.localizers.base import DirectionEstimate, direction_grid
from tracker.audio.localizers.spectra import SrpGrid
from tracker.audio.localizers.srp_phat import SrpPhat
from tracker.audio.map_tracking import MapTracker, MapTrackerSettings
from tracker.audio.trackers import TRACKERS, TrackerName
from tracker.audio.trackers import choose_tracker as choose_tracker  # re-exported
from tracker.audio.tracking import TalkerTracker, TrackerSettings, TrackPoint
from tracker.audio.vad import SpeechDetector, VadSettings
from tracker.errors import ConfigError, DataError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class WindowSettings:
    """Analysis windows: ``window_s`` long, one every ``hop_s``.

    ``fine_window_s`` (optional, longer) is a second window ending with each short one; its
    estimate refines the current talker's position in the tracker (the short one reacts).
    """

    window_s: float = 0.5
    hop_s: float = 0.1
    fine_window_s: float | None = None

    def __post_init__(self) -> None:
        if not 0.05 <= self.window_s <= 10.0:
            raise ConfigError(f"window_s={self.window_s} outside 0.05-10 s")
        if not 0.01 <= self.hop_s <= self.window_s:
            raise ConfigError(f"hop_s={self.hop_s} must be in 0.01 s..window_s")
        if self.fine_window_s is not None and not self.window_s < self.fine_window_s <= 10.0:
            raise ConfigError(f"fine_window_s={self.fine_window_s} must be in window_s..10 s")


@dataclass(frozen=True, slots=True)
class FrameEstimate:
    """One analysis window's raw estimate.

    ``t_s`` is the window centre, ``end_s`` the moment a live system would have it.
    ``power_map`` (only for the map tracker) is the short window's steered response, shape
    (n_map,), over :attr:`Pipeline.map_azimuth_rad` (the base frame) or, for a head-mounted
    array before :func:`tracker.audio.head.frames_to_base`, over
    :attr:`Pipeline.steer_azimuth_rad` (the head frame); it takes no part in equality.
    """

    t_s: float
    end_s: float
    azimuth_rad: float
    elevation_rad: float | None
    confidence: float
    speech: bool
    fine_azimuth_rad: float | None = None
    power_map: FloatArray | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class LocateResult:
    """Per-window estimates and the camera track (one point per window)."""

    fs_hz: int
    method: str
    frames: tuple[FrameEstimate, ...]
    track: tuple[TrackPoint, ...]

    def to_dict(self) -> dict[str, Any]:
        """The ``tracker audio locate --json`` object (degrees, seconds)."""

        def deg(value: float | None) -> float | None:
            return None if value is None else round(float(np.rad2deg(value)), 3)

        return {
            "fs": int(self.fs_hz),
            "frames": [
                {
                    "t": round(f.t_s, 4),
                    "azimuth_deg": deg(f.azimuth_rad),
                    "elevation_deg": deg(f.elevation_rad),
                    "confidence": round(float(f.confidence), 4),
                    "speech": bool(f.speech),
                }
                for f in self.frames
            ],
            "track": [
                {"t": round(p.t_s, 4), "azimuth_deg": deg(p.azimuth_rad),
                 "elevation_deg": deg(p.elevation_rad)}
                for p in self.track
            ],
        }


MAP_STEP_RAD = float(np.deg2rad(1.0))


@dataclass
class Pipeline:
    """VAD + localizer + talker tracker bound to one array and sample rate.

    ``tracker`` chooses the talker tracker: ``"kalman"`` (:mod:`tracker.audio.tracking`, fed
    the short and long windows' peaks) or ``"map"`` (:mod:`tracker.audio.map_tracking`, fed
    each short window's steered-response map over a 1° azimuth grid, computed from the same
    cross-spectra as its estimate; needs the ``srp_phat`` localizer).

    ``base_azimuth_range_rad`` (head-mounted arrays with the map tracker, required there): the
    base-frame azimuth range (rad) where talkers can be, the map tracker's fixed grid
    :attr:`map_azimuth_rad`. The maps are steered over the localizer's range in the head frame
    (:attr:`steer_azimuth_rad`) and turned into the base frame window by window with the head's
    angles (:func:`tracker.audio.head.map_to_base`). A room-mounted array's maps are steered
    straight on the base grid (the localizer's ``azimuth_range_rad``).
    """

    array: MicArray
    fs_hz: int
    method: str = DEFAULT_LOCALIZER
    windows: WindowSettings = field(default_factory=WindowSettings)
    vad: VadSettings = field(default_factory=VadSettings)
    tracking: TrackerSettings = field(default_factory=TrackerSettings)
    localizer_options: dict[str, Any] = field(default_factory=dict)
    fine_lag_fraction: float = 1.0
    tracker: TrackerName = "kalman"
    map_tracking: MapTrackerSettings = field(default_factory=MapTrackerSettings)
    base_azimuth_range_rad: tuple[float, float] | None = None
    localizer: Localizer = field(init=False)
    map_azimuth_rad: FloatArray = field(init=False)
    steer_azimuth_rad: FloatArray = field(init=False)
    _map_grid: SrpGrid | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        if self.tracker not in TRACKERS:
            raise ConfigError(f"unknown tracker {self.tracker!r}; choose one of: {', '.join(TRACKERS)}")
        self.localizer = make_localizer(self.method, self.array, self.fs_hz,
                                        **self.localizer_options)
        self.map_azimuth_rad = self.steer_azimuth_rad = np.zeros(0)
        if self.base_azimuth_range_rad is not None and not self.array.head_mounted:
            raise ConfigError(f"base_azimuth_range_rad applies to head-mounted arrays; {self.array.name} "
                              "is room-mounted: its localizer's azimuth_range_rad is in the base frame")
        if self.tracker == "map":
            self._build_map_grids()

    def _build_map_grids(self) -> None:
        """The 1° azimuth grids: the maps' steering grid (the localizer's azimuth range, in
        the array's frame) and the tracker's base-frame grid (the same for a room-mounted array)."""
        if not isinstance(self.localizer, SrpPhat):
            raise ConfigError(f"the map tracker needs the srp_phat localizer, not {self.method!r}")
        az_range = self.localizer_options.get("azimuth_range_rad")
        steer_az, _ = direction_grid(self.array, MAP_STEP_RAD, np.pi, az_range)
        self.steer_azimuth_rad = self.map_azimuth_rad = np.unique(steer_az)
        if self.array.head_mounted:
            base = self.base_azimuth_range_rad
            if base is None:
                raise ConfigError(f"the map tracker with a head-mounted array ({self.array.name}) "
                                  "needs base_azimuth_range_rad, the base-frame range where talkers "
                                  "can be (its grid is a line, not a circle); or use tracker='kalman'")
            lo, hi = base
            if not (-2 * np.pi <= lo < hi <= lo + 2 * np.pi and hi <= 2 * np.pi):
                raise ConfigError(f"base_azimuth_range_rad={base} must be increasing, within ±2π "
                                  "and at most a full turn")
            self.map_azimuth_rad = np.linspace(lo, hi, max(3, int(round((hi - lo) / MAP_STEP_RAD)) + 1))
        self._map_grid = SrpGrid(self.array, self.fs_hz, self.steer_azimuth_rad,
                                 np.zeros_like(self.steer_azimuth_rad), self.localizer.settings)

    def locate_with_map(self, frame: FloatArray) -> tuple[DirectionEstimate, FloatArray]:
        """One window's estimate (``localizer.locate``'s) and its azimuth map, one STFT.

        The map is the steered response (mean PHAT-weighted GCC over pairs) of the GCCs the
        estimate came from, at :attr:`steer_azimuth_rad` and zero elevation (in the array's
        frame; for a room-mounted array that is :attr:`map_azimuth_rad`); shape (n_steer,).
        """
        if self._map_grid is None or not isinstance(self.localizer, SrpPhat):
            raise ConfigError("azimuth maps are computed only for tracker='map'")
        estimate, g = self.localizer.locate_with_gcc(frame)
        return estimate, self._map_grid.response(g)

    def estimate_frames(self, audio: FloatArray) -> tuple[FrameEstimate, ...]:
        """Raw estimate of every window of ``audio``, shape (n_mics, n_samples)."""
        audio = check_recording(audio, self.array, self.fs_hz, self.windows.window_s)
        detector = SpeechDetector(self.fs_hz, self.vad)
        features = detector.features(audio.mean(axis=0))
        n_win = int(round(self.windows.window_s * self.fs_hz))
        n_hop = int(round(self.windows.hop_s * self.fs_hz))
        fine_s = self.windows.fine_window_s
        n_fine = int(round(fine_s * self.fs_hz)) if fine_s is not None else 0
        frames = []
        for start in range(0, audio.shape[1] - n_win + 1, n_hop):
            start_s, end_s = start / self.fs_hz, (start + n_win) / self.fs_hz
            speech = detector.window_is_speech(features, start_s, end_s)
            power_map = None
            if self.tracker == "map":
                estimate, power_map = self.locate_with_map(audio[:, start : start + n_win])
            else:
                estimate = self.localizer.locate(audio[:, start : start + n_win])
            fine = None
            if speech and n_fine:
                lo = max(0, start + n_win - n_fine)
                fine = self.localizer.locate(audio[:, lo : start + n_win]).azimuth_rad
            frames.append(FrameEstimate(0.5 * (start_s + end_s), end_s, estimate.azimuth_rad,
                                        estimate.elevation_rad, estimate.confidence, speech,
                                        fine, power_map))
        return tuple(frames)

    def track(self, frames: tuple[FrameEstimate, ...]) -> tuple[TrackPoint, ...]:
        """Run the talker tracker over frames in time order (fresh tracker each call)."""
        if self.tracker == "map":
            return self._track_maps(frames)
        tracker = TalkerTracker(self.tracking)
        fine_s = self.windows.fine_window_s
        lag_s = self.fine_lag_fraction * 0.5 * (fine_s - self.windows.window_s) if fine_s else 0.0
        return tuple(
            tracker.step(f.t_s, f.azimuth_rad, f.elevation_rad, f.confidence, f.speech,
                         f.fine_azimuth_rad, lag_s)
            for f in frames
        )

    def _track_maps(self, frames: tuple[FrameEstimate, ...]) -> tuple[TrackPoint, ...]:
        tracker = MapTracker(self.map_azimuth_rad, self.map_tracking)
        out = []
        for f in frames:
            if f.power_map is None:
                raise DataError(f"frame at t={f.t_s:.3f} s has no azimuth map (estimated for "
                                "another tracker?)")
            if self.array.head_mounted and f.power_map.shape != self.map_azimuth_rad.shape:
                raise DataError(f"frame at t={f.t_s:.3f} s has a head-frame map: a head-mounted "
                                "array's frames go through tracker.audio.head.locate_head_mounted")
            out.append(tracker.step(f.t_s, f.power_map, f.elevation_rad, f.speech, f.confidence))
        return tuple(out)

    def run(self, audio: FloatArray) -> LocateResult:
        """Frames and track of a whole recording."""
        frames = self.estimate_frames(audio)
        return LocateResult(self.fs_hz, self.method, frames, self.track(frames))


def check_recording(audio: FloatArray, array: MicArray, fs_hz: int, window_s: float
                    ) -> FloatArray:
    """Validate a recording against the array; returns float64 (n_mics, n_samples)."""
    audio = np.asarray(audio, dtype=float)
    if audio.ndim != 2 or audio.shape[0] != array.n_mics:
        channels = audio.shape[0] if audio.ndim == 2 else 1
        raise DataError(
            f"recording has {channels} channel(s) but {array.name} has {array.n_mics} mics"
        )
    if audio.shape[1] < int(window_s * fs_hz):
        raise DataError(
            f"recording is {audio.shape[1] / fs_hz:.3f} s long, shorter than one "
            f"{window_s} s window"
        )
    if not np.all(np.isfinite(audio)):
        raise DataError("recording contains NaN or infinite samples")
    if float(np.max(np.abs(audio))) < 1e-6:
        raise DataError("recording is silent (all samples below 1e-6 full scale)")
    return audio
