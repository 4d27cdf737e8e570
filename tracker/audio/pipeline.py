"""Recording in, per-window estimates and the tracked camera direction out (offline or streamed)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.audio.array import FieldOfView, MicArray
from tracker.audio.localizers import DEFAULT_LOCALIZER, Localizer, make_localizer
from tracker.audio.localizers.base import DirectionEstimate, direction_grid
from tracker.audio.localizers.frames import StftFrames
from tracker.audio.localizers.spectra import GccTable, SrpGrid
from tracker.audio.localizers.srp_phat import SrpPhat
from tracker.audio.map_tracking import MapTracker, MapTrackerSettings
from tracker.audio.trackers import TRACKERS as TRACKERS  # re-exported
from tracker.audio.trackers import TrackerName as TrackerName
from tracker.audio.trackers import choose_tracker as choose_tracker
from tracker.audio.tracking import TalkerTracker, TrackerSettings, TrackPoint
from tracker.audio.vad import SpeechDetector, VadSettings
from tracker.errors import ConfigError, DataError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

_CHUNK_WINDOWS = 16  # windows localized together (bounds the frames held: ~3 MB at 4 mics)
ANALYSIS_GRID_FRAMES = 2  # analysis starts on a grid of 1 / this of the frame hop


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
_MAP_EL_STEP_RAD = float(np.deg2rad(5.0))


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

    ``estimate_fine``: localize the long windows (``windows.fine_window_s``) even when the
    tracker does not read them (True; the map tracker reads only the short windows' maps) or
    never (False); None (default): when the tracker reads them.

    With ``srp_phat`` every STFT frame is computed once and shared by all the windows holding
    it (:class:`~tracker.audio.localizers.frames.StftFrames`; the windows start on two frame
    grids, :meth:`analysis_start`), windows are localized in chunks of 16
    (:meth:`estimate_windows`); other localizers take one window at a time.
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
    estimate_fine: bool | None = None
    localizer: Localizer = field(init=False)
    map_azimuth_rad: FloatArray = field(init=False)
    steer_azimuth_rad: FloatArray = field(init=False)
    view: FieldOfView = field(init=False)
    _map_grid: SrpGrid | None = field(init=False, default=None)
    _map_elevations: FloatArray = field(init=False)

    def __post_init__(self) -> None:
        if self.tracker not in TRACKERS:
            raise ConfigError(f"unknown tracker {self.tracker!r}; choose one of: {', '.join(TRACKERS)}")
        self.localizer = make_localizer(self.method, self.array, self.fs_hz,
                                        **self.localizer_options)
        self.map_azimuth_rad = self.steer_azimuth_rad = np.zeros(0)
        if self.base_azimuth_range_rad is not None and not self.array.head_mounted:
            raise ConfigError(f"base_azimuth_range_rad applies to head-mounted arrays; {self.array.name} "
                              "is room-mounted: its localizer's azimuth_range_rad is in the base frame")
        self.view = self._tracking_view()
        if self.tracker == "map":
            self._build_map_grids()

    def _tracking_view(self) -> FieldOfView:
        """Where talkers are tracked, in the base frame: the localizer's azimuth range for an
        array fixed to the base (``azimuth_range_rad``, else the array's field of view), the
        base range for a head-mounted one (``base_azimuth_range_rad``, else its field of view)."""
        fov = self.array.field_of_view
        if self.array.head_mounted:
            base = self.base_azimuth_range_rad
            if base is None:
                return fov
            lo, hi = base
            if not (-2 * np.pi <= lo < hi <= lo + 2 * np.pi and hi <= 2 * np.pi):
                raise ConfigError(f"base_azimuth_range_rad={base} must be increasing, within ±2π "
                                  "and at most a full turn")
            return FieldOfView(base, fov.elevation_rad)
        search = self.localizer_options.get("azimuth_range_rad")
        if search is None:
            if not self.array.resolves_front_back and fov.full_circle:
                return FieldOfView((-np.pi / 2, np.pi / 2), fov.elevation_rad)
            return fov
        return FieldOfView((float(search[0]), float(search[1])), fov.elevation_rad)

    @property
    def map_circular(self) -> bool:
        """True when the map tracker's grid is the full circle (it wraps at ±180°)."""
        return self.tracker == "map" and self.view.full_circle

    def _build_map_grids(self) -> None:
        """The 1° azimuth grids: the maps' steering grid (the localizer's azimuth range, in
        the array's frame) and the tracker's base-frame grid (the same for a room-mounted array:
        a line over a limited view, a circle over the full one).

        The maps are steered at zero elevation, or, when the array's view lies on one side of
        the horizontal (a ceiling's, a table's for an array with height), at the best of the
        localizer's elevations for each azimuth.
        """
        if not isinstance(self.localizer, SrpPhat):
            raise ConfigError(f"the map tracker needs the srp_phat localizer, not {self.method!r}")
        az_range = self.localizer_options.get("azimuth_range_rad")
        steer_az, _ = direction_grid(self.array, MAP_STEP_RAD, np.pi, az_range)
        self.steer_azimuth_rad = self.map_azimuth_rad = np.unique(steer_az)
        if self.array.head_mounted:
            lo, hi = self.view.azimuth_rad
            if self.view.full_circle:
                self.map_azimuth_rad = np.arange(-np.pi, np.pi - 0.5 * MAP_STEP_RAD, MAP_STEP_RAD)
            else:
                self.map_azimuth_rad = np.linspace(lo, hi, max(3, int(round((hi - lo) / MAP_STEP_RAD))
                                                   + 1))
        elevations = self.array.elevation_range_rad
        self._map_elevations = np.zeros(1)
        if elevations is not None and not elevations[0] <= 0.0 <= elevations[1]:
            lo, hi = elevations
            self._map_elevations = np.linspace(lo, hi, max(1, int(round((hi - lo) / _MAP_EL_STEP_RAD)))
                                               + 1)
        az_grid, el_grid = np.meshgrid(self.steer_azimuth_rad, self._map_elevations, indexing="ij")
        self._map_grid = SrpGrid(self.array, self.fs_hz, az_grid.ravel(), el_grid.ravel(),
                                 self.localizer.settings)

    def _map_response(self, gcc: GccTable) -> FloatArray:
        """Azimuth maps of GCC tables (one window's, or a stack): the steered response at each
        steering azimuth, best over the map's elevations; shape (..., n_steer)."""
        assert self._map_grid is not None
        response = self._map_grid.response(gcc)
        n_el = self._map_elevations.size
        if n_el == 1:
            return response
        return np.asarray(response.reshape(*response.shape[:-1], -1, n_el).max(axis=-1))

    def locate_with_map(self, frame: FloatArray) -> tuple[DirectionEstimate, FloatArray]:
        """One window's estimate (``localizer.locate``'s) and its azimuth map, one STFT.

        The map is the steered response (mean PHAT-weighted GCC over pairs) of the GCCs the
        estimate came from, at :attr:`steer_azimuth_rad` and zero elevation (in the array's
        frame; for a room-mounted array that is :attr:`map_azimuth_rad`); shape (n_steer,).
        """
        if self._map_grid is None or not isinstance(self.localizer, SrpPhat):
            raise ConfigError("azimuth maps are computed only for tracker='map'")
        estimate, g = self.localizer.locate_with_gcc(frame)
        return estimate, self._map_response(g)

    @property
    def estimates_fine(self) -> bool:
        """True when the long windows are localized: there is one, and the tracker reads it
        (the Kalman tracker does, the map tracker does not) or ``estimate_fine`` asks for it."""
        if self.windows.fine_window_s is None:
            return False
        return self.tracker == "kalman" if self.estimate_fine is None else self.estimate_fine

    def speech_windows(self, audio: FloatArray) -> tuple[IntArray, BoolArray]:
        """Start samples of every window of ``audio`` (n_mics, n_samples) and the speech
        detector's decision on each; shape (n_windows,) each."""
        detector = SpeechDetector(self.fs_hz, self.vad)
        features = detector.features(audio.mean(axis=0))
        n_win = int(round(self.windows.window_s * self.fs_hz))
        n_hop = int(round(self.windows.hop_s * self.fs_hz))
        starts = np.arange(0, audio.shape[1] - n_win + 1, n_hop, dtype=np.int64)
        speech = detector.windows_are_speech(features, starts / self.fs_hz,
                                             (starts + n_win) / self.fs_hz)
        return starts, speech

    def estimate_frames(self, audio: FloatArray) -> tuple[FrameEstimate, ...]:
        """Raw estimate of every window of ``audio``, shape (n_mics, n_samples)."""
        audio = check_recording(audio, self.array, self.fs_hz, self.windows.window_s)
        starts, speech = self.speech_windows(audio)
        return tuple(self.estimate_windows(audio, 0, starts, speech))

    def new_frames(self) -> StftFrames | None:
        """A store of STFT frames shared by the windows (None for localizers that take one
        window at a time)."""
        return self.localizer.new_frames() if isinstance(self.localizer, SrpPhat) else None

    def first_sample_needed(self, start: int) -> int:
        """The earliest sample the window starting at ``start`` (and its long window) reads
        (their analysis starts on the frame grid, :meth:`analysis_start`)."""
        n_win, n_fine = self._lengths()
        return int(self.analysis_start(np.array([max(0, min(start, start + n_win - n_fine))]))[0])

    def analysis_start(self, starts: IntArray) -> IntArray:
        """Where the windows starting at ``starts`` are analysed: with ``srp_phat``, at or
        before the start on a grid of half the STFT frame hop (``nfft // 4`` samples, 8 ms at
        16 kHz, :data:`ANALYSIS_GRID_FRAMES`), so the windows of a recording read two sets of
        frames, each frame transformed once (windows every 0.1 s = 1600 samples on a
        256-sample hop otherwise lie on four grids: every frame computed four times).

        Why two grids and not one: on one grid consecutive windows share most of their frames
        exactly and their errors come in runs, which the trackers follow (12 meetings, 4 mics,
        the full circle: tracked >10° off 2.7 % of turn time on one grid, 1.8 % on four, 1.2 %
        on two; docs/audio.md section 8). A window's analysis ends up to 127 samples before its
        nominal end (never after it: a live system has its samples when the window ends); its
        time stamps stay the nominal ones. Other localizers: ``starts``.
        """
        starts = np.asarray(starts, dtype=np.int64)
        if not isinstance(self.localizer, SrpPhat):
            return starts
        grid = max(1, self.localizer.settings.nfft // 2 // ANALYSIS_GRID_FRAMES)
        return np.asarray(starts - starts % grid, dtype=np.int64)

    def _lengths(self) -> tuple[int, int]:
        """Samples in a short window and in a long one (0 when long ones are not localized)."""
        n_win = int(round(self.windows.window_s * self.fs_hz))
        fine_s = self.windows.fine_window_s
        n_fine = int(round(fine_s * self.fs_hz)) if fine_s is not None and self.estimates_fine else 0
        return n_win, n_fine

    def estimate_windows(self, audio: FloatArray, offset: int, starts: IntArray,
                         speech: BoolArray, frames: StftFrames | None = None
                         ) -> list[FrameEstimate]:
        """Raw estimates of the windows starting at ``starts`` (absolute samples, increasing).

        ``audio`` (n_mics, n) holds samples ``offset..offset + n``, every window and its long
        window inside from their :meth:`analysis_start`; ``speech`` (n_windows,) is the speech
        detector's decision on each (long windows are localized for speech windows only).
        ``frames`` (from :meth:`new_frames`), when given, keeps STFT frames between calls (a
        stream's next windows reuse them); without it a recording's windows are localized in
        chunks of time with a store of their own.
        """
        fs = self.fs_hz
        n_win, n_fine = self._lengths()
        starts = np.asarray(starts, dtype=np.int64)
        ends = starts + n_win
        speech = np.asarray(speech, dtype=bool)
        if isinstance(self.localizer, SrpPhat):
            located = self._locate_srp(audio, offset, starts, speech, frames)
        else:
            located = self._locate_each(audio, offset, starts, speech)
        out = []
        for k in range(starts.size):
            start_s, end_s = int(starts[k]) / fs, int(ends[k]) / fs
            estimate, fine, power_map = located[k]
            out.append(FrameEstimate(0.5 * (start_s + end_s), end_s, estimate.azimuth_rad,
                                     estimate.elevation_rad, estimate.confidence,
                                     bool(speech[k]), fine, power_map))
        return out

    def _locate_each(self, audio: FloatArray, offset: int, starts: IntArray, speech: BoolArray
                     ) -> list[tuple[DirectionEstimate, float | None, FloatArray | None]]:
        """One window at a time (localizers without shared frames)."""
        n_win, n_fine = self._lengths()
        out = []
        for start, is_speech in zip(starts.tolist(), speech.tolist(), strict=True):
            window = audio[:, start - offset : start + n_win - offset]
            power_map = None
            if self.tracker == "map":
                estimate, power_map = self.locate_with_map(window)
            else:
                estimate = self.localizer.locate(window)
            fine = None
            if is_speech and n_fine:
                lo = max(0, start + n_win - n_fine)
                fine = self.localizer.locate(audio[:, lo - offset : start + n_win - offset]
                                             ).azimuth_rad
            out.append((estimate, fine, power_map))
        return out

    def _locate_srp(self, audio: FloatArray, offset: int, starts: IntArray, speech: BoolArray,
                    frames: StftFrames | None
                    ) -> list[tuple[DirectionEstimate, float | None, FloatArray | None]]:
        """Every short window and the long windows of the speech windows, over shared frames.

        The jobs (window start, length) are localized grouped by length, each from its
        :meth:`analysis_start` (two frame grids); a recording (no ``frames`` given) is done in
        chunks of time with one store of frames, so the frames held stay few.
        """
        assert isinstance(self.localizer, SrpPhat)
        n_win, n_fine = self._lengths()
        fine_windows = np.flatnonzero(speech) if n_fine else np.zeros(0, dtype=np.int64)
        fine_lo = np.maximum(0, starts[fine_windows] + n_win - n_fine)
        job_start = self.analysis_start(np.concatenate([starts, fine_lo]))
        job_length = np.concatenate([np.full(starts.size, n_win),
                                     starts[fine_windows] + n_win - fine_lo])
        n_short = starts.size
        azimuth, elevation, confidence = (np.empty(job_start.size) for _ in range(3))
        maps = (np.empty((n_short, self.steer_azimuth_rad.size))
                if self._map_grid is not None else None)
        if frames is not None:
            self._locate_jobs(frames, audio, offset, job_start, job_length, n_short,
                              np.arange(job_start.size), azimuth, elevation, confidence, maps)
        else:
            store = self.localizer.new_frames()  # every job starts on the one frame grid
            members = np.argsort(job_start, kind="stable")
            for i in range(0, members.size, _CHUNK_WINDOWS):
                chunk = members[i : i + _CHUNK_WINDOWS]
                store.forget_before(int(job_start[chunk[0]]))  # earlier jobs are done
                self._locate_jobs(store, audio, offset, job_start, job_length, n_short,
                                  chunk, azimuth, elevation, confidence, maps)
        fine: list[float | None] = [None] * n_short
        for j, k in enumerate(fine_windows.tolist()):
            fine[k] = float(azimuth[n_short + j])
        resolves = self.array.sees_elevation
        return [(DirectionEstimate(float(azimuth[k]),
                                   float(elevation[k]) if resolves else None,
                                   float(confidence[k])),
                 fine[k], None if maps is None else maps[k]) for k in range(n_short)]

    def _locate_jobs(self, store: StftFrames, audio: FloatArray, offset: int,
                     job_start: IntArray, job_length: IntArray, n_short: int, jobs: IntArray,
                     azimuth: FloatArray, elevation: FloatArray, confidence: FloatArray,
                     maps: FloatArray | None) -> None:
        """Localize ``jobs`` (indices into ``job_start``/``job_length``; the first ``n_short``
        jobs are the short windows, which also get maps) into the output arrays."""
        assert isinstance(self.localizer, SrpPhat)
        for length in np.unique(job_length[jobs]):
            some = jobs[job_length[jobs] == length]
            frame_starts = job_start[some, None] + self.localizer.frame_starts(0, int(length))
            store.add(audio, offset, frame_starts)
            short = some < n_short
            # Of a long window only the azimuth is read: no confidence weighting.
            located = self.localizer.locate_rows(store, store.rows(frame_starts),
                                                 with_confidence=bool(np.any(short)))
            azimuth[some], elevation[some] = located.azimuth_rad, located.elevation_rad
            confidence[some] = located.confidence
            if maps is not None and self._map_grid is not None and np.any(short):
                tables = GccTable(located.gcc.values[short], located.gcc.first_lag)
                maps[some[short]] = np.atleast_2d(self._map_response(tables))

    def track(self, frames: tuple[FrameEstimate, ...]) -> tuple[TrackPoint, ...]:
        """Run the talker tracker over frames in time order (fresh tracker each call)."""
        if self.tracker == "map":
            return self._track_maps(frames)
        tracker = TalkerTracker(self.tracking, self.view)
        fine_s = self.windows.fine_window_s
        lag_s = self.fine_lag_fraction * 0.5 * (fine_s - self.windows.window_s) if fine_s else 0.0
        return tuple(
            tracker.step(f.t_s, f.azimuth_rad, f.elevation_rad, f.confidence, f.speech,
                         f.fine_azimuth_rad, lag_s)
            for f in frames
        )

    def _track_maps(self, frames: tuple[FrameEstimate, ...]) -> tuple[TrackPoint, ...]:
        tracker = MapTracker(self.map_azimuth_rad, self.map_tracking, self.map_circular)
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
