"""Streaming localisation: audio blocks in, the talker tracker's latest target out.

:class:`StreamingLocator` takes blocks of multichannel audio as they arrive (from any
:class:`~tracker.audio.sources.AudioSource`: a WAV file, a simulated room, live capture),
keeps a ring buffer of the last few seconds, and for every analysis hop runs the same
localizer windows (short, long ``fine_window_s``) and speech detector as
the batch :class:`~tracker.audio.pipeline.Pipeline`, feeding one persistent
:class:`~tracker.audio.tracking.TalkerTracker` (or, for ``Pipeline(tracker="map")``, each
window's azimuth map to one :class:`~tracker.audio.map_tracking.MapTracker`) frame by
frame. Streaming a recording block by
block gives the batch pipeline's frames and track (the speech detector is computed on a
window of buffered audio with enough history for its noise floor and enough look-ahead for
its modulation test, so its decisions match the whole-recording ones).

A frame is processed once the audio reaches its window end plus the speech detector's
look-ahead (about 0.3 s with the default VAD settings): that is the streaming latency on
top of the half window.

A head-mounted array (``"mount": "head"``) measures in the head frame: the producer gives the
head's encoder angles on the stream's clock (``push(block, head_pan_rad=..., head_tilt_rad=...)``
for the angles while the block was recorded, or time-stamped readings in :attr:`head_poses`),
and every window's estimate (and, for the map tracker, its azimuth map, resampled onto the
tracker's base-frame grid) is turned into the base frame with the head's power-weighted mean
rotation over that window (:mod:`tracker.audio.head`) before the tracker sees it; targets and
kept frames are in the base frame. A room-mounted array's estimates are already in the base
frame: nothing changes for it.

:class:`StreamTargetSource` exposes the latest target to the engine (``name``,
``target_at``, see :mod:`tracker.targets`).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.audio.head import MAX_SWEEP_RAD, HeadPoses, frame_to_base, map_grids, window_motion
from tracker.audio.map_tracking import MapTracker
from tracker.audio.pipeline import FrameEstimate, Pipeline
from tracker.audio.policy import CameraPolicy
from tracker.audio.tracking import TalkerTracker, TrackPoint
from tracker.audio.vad import SpeechDetector, StreamingSpeechDetector
from tracker.errors import ConfigError, DataError
from tracker.targets import Target

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class StreamTarget:
    """The tracker's output after one streamed frame.

    Attributes
    ----------
    t_s : window centre (s of stream time, from the first sample).
    end_s : window end (s); the frame was computed once the audio reached ``ready_s``.
    ready_s : stream time at which this target became available (window end + VAD look-ahead).
    azimuth_rad, elevation_rad : camera target (elevation None if unknown); NaN azimuth
        before the first shot.
    shot : "none", "talker" or "wide".
    talker_id : small integer per distinct talker direction seen (None unless shot is "talker").
    talker_azimuth_rad : smoothed direction of the current talker (None if none).
    confidence : the localizer's confidence for this frame's short window.
    speech : the speech detector's decision for this frame.
    estimate_azimuth_rad : the localizer's raw short-window azimuth (base frame).
    """

    t_s: float
    end_s: float
    ready_s: float
    azimuth_rad: float
    elevation_rad: float | None
    shot: str
    talker_id: int | None
    talker_azimuth_rad: float | None
    confidence: float
    speech: bool
    estimate_azimuth_rad: float


@dataclass(frozen=True, slots=True)
class TalkerSeen:
    """A talker the stream has followed (one per direction the tracker took, ids from 0).

    Attributes
    ----------
    talker_id : the id :attr:`StreamTarget.talker_id` gives her shots.
    azimuth_rad, elevation_rad : where she was last (base frame; elevation None if unknown).
    first_s, last_spoken_s : stream times of her first frame and her last speech frame.
    speaking_s : how long she has talked (speech frames pointing at her while she was the
        talker).
    speaking : she is the current talker and spoke within the last ``SPEAKING_HOLD_S``.
    """

    talker_id: int
    azimuth_rad: float
    elevation_rad: float | None
    first_s: float
    last_spoken_s: float
    speaking_s: float
    speaking: bool


SPEAKING_HOLD_S = 0.5  # a talker's pause shorter than this still shows her as speaking


class StreamingLocator:
    """Incremental :class:`Pipeline`: :meth:`push` blocks, read :attr:`latest` (thread-safe).

    Parameters
    ----------
    pipeline : the batch pipeline whose localizer, windows, VAD and tracker settings are used.
    talker_separation_rad : talker directions further apart than this get different ids.
    head_poses : for a head-mounted array, the head's angle history (stream clock) that a
        producer fills; a new empty one by default. Refused for a room-mounted array.
    """

    def __init__(self, pipeline: Pipeline, talker_separation_rad: float = math.radians(15.0),
                 head_poses: HeadPoses | None = None) -> None:
        self.pipeline = pipeline
        array = pipeline.array
        if head_poses is not None and not array.head_mounted:
            raise ConfigError(f"{array.name} is room-mounted: head angles do not apply "
                              '(set "mount": "head" if it rides on the pan/tilt head)')
        self.head_poses = head_poses if head_poses is not None else (
            HeadPoses() if array.head_mounted else None)
        self.max_head_sweep_rad = MAX_SWEEP_RAD
        fs = pipeline.fs_hz
        w = pipeline.windows
        self._n_win = int(round(w.window_s * fs))
        self._n_hop = int(round(w.hop_s * fs))
        self._n_fine = int(round(w.fine_window_s * fs)) if w.fine_window_s is not None else 0
        self._detector = SpeechDetector(fs, pipeline.vad)
        # The speech detector measures each of its frames once as blocks arrive; it keeps the
        # history its decisions need (noise floor, smoothing) and decides a window once the
        # look-ahead after its end has arrived (samples).
        self._speech = StreamingSpeechDetector(self._detector)
        self._vad_history = self._detector.history_samples
        self.lookahead = self._detector.lookahead_samples
        # The localizer's STFT frames, each computed once and shared by the windows holding it.
        self._stft = pipeline.new_frames()
        fine_s, short_s = w.fine_window_s, w.window_s
        self._lag_s = pipeline.fine_lag_fraction * 0.5 * (fine_s - short_s) if fine_s else 0.0
        self._separation_rad = float(talker_separation_rad)
        self._tracker = TalkerTracker(pipeline.tracking, pipeline.view)
        # Pipeline(tracker="map"): each window's azimuth map feeds the map tracker instead.
        self._map_tracker = (MapTracker(pipeline.map_azimuth_rad, pipeline.map_tracking,
                                        pipeline.map_circular)
                             if pipeline.tracker == "map" else None)
        self._buf = np.zeros((pipeline.array.n_mics, 0))
        self._buf_start = 0  # absolute sample index of self._buf[:, 0]
        self._next = 0  # index of the next frame to compute
        self._talkers: list[list[Any]] = []  # per id: [azimuth, elevation, first, last spoken, total]
        self._current_id: int | None = None
        self._last_t_s = -math.inf
        self._lock = threading.Lock()
        self._latest: StreamTarget | None = None
        self._pending_policy: CameraPolicy | None = None
        self.frames: list[FrameEstimate] = []
        self.keep_frames = False
        self.compute_s = 0.0  # CPU (thread) time spent in push/finish, s

    @property
    def fs_hz(self) -> int:
        return self.pipeline.fs_hz

    @property
    def samples_in(self) -> int:
        """Samples received so far (per channel)."""
        return self._buf_start + self._buf.shape[1]

    @property
    def latest(self) -> StreamTarget | None:
        """The most recent target, or None before the first frame."""
        with self._lock:
            return self._latest

    @property
    def policy(self) -> CameraPolicy:
        """The camera-operator policy in force (or about to be: see :meth:`set_policy`)."""
        with self._lock:
            pending = self._pending_policy
        if pending is not None:
            return pending
        return CameraPolicy.of(self.pipeline.map_tracking if self._map_tracker is not None
                               else self.pipeline.tracking)

    def set_policy(self, policy: CameraPolicy) -> None:
        """Use ``policy`` from the next frame on (thread-safe; the tracker keeps its state:
        its talkers, seats and current shot)."""
        with self._lock:
            self._pending_policy = policy

    def _apply_pending_policy(self) -> None:
        with self._lock:
            policy, self._pending_policy = self._pending_policy, None
        if policy is None:
            return
        self.pipeline.tracking = policy.apply(self.pipeline.tracking)
        self.pipeline.map_tracking = policy.apply(self.pipeline.map_tracking)
        self._tracker.settings = self.pipeline.tracking
        if self._map_tracker is not None:
            self._map_tracker.settings = self.pipeline.map_tracking

    def push(self, block: FloatArray, head_pan_rad: float | None = None,
             head_tilt_rad: float | None = None) -> list[StreamTarget]:
        """Add a block, shape (n_mics, n_samples); returns the targets of the frames it completed.

        ``head_pan_rad``/``head_tilt_rad`` (head-mounted arrays only): the head's angles while
        the block was recorded, recorded at the block's centre time (finer time-stamped
        readings go to :attr:`head_poses` directly).
        """
        block = np.asarray(block, dtype=float)
        n_mics = self.pipeline.array.n_mics
        if block.ndim != 2 or block.shape[0] != n_mics:
            got = block.shape[0] if block.ndim == 2 else f"shape {block.shape}"
            raise DataError(f"audio block has {got} channel(s); "
                            f"{self.pipeline.array.name} has {n_mics} mics")
        if not np.all(np.isfinite(block)):
            raise DataError("audio block contains NaN or infinite samples")
        if head_pan_rad is not None or head_tilt_rad is not None:
            if self.head_poses is None:
                raise ConfigError(f"{self.pipeline.array.name} is room-mounted: head angles "
                                  "do not apply")
            if head_pan_rad is None or head_tilt_rad is None:
                raise ConfigError("give both head_pan_rad and head_tilt_rad")
            centre_s = (self.samples_in + 0.5 * block.shape[1]) / self.fs_hz
            self.head_poses.add(centre_s, float(head_pan_rad), float(head_tilt_rad))
        self._buf = np.concatenate([self._buf, block], axis=1)
        self._speech.push(block.mean(axis=0))
        return self._run(final=False)

    def finish(self) -> list[StreamTarget]:
        """The source ended: process the frames left (their VAD look-ahead is cut by the end)."""
        return self._run(final=True)

    def _run(self, final: bool) -> list[StreamTarget]:
        import time

        t0 = time.thread_time()
        total = self.samples_in
        ready = []
        k = self._next
        while True:
            end = k * self._n_hop + self._n_win
            if end > total or (not final and end + self.lookahead > total):
                break
            ready.append(k)
            k += 1
        out: list[StreamTarget] = []
        if ready:
            out = self._frames(ready, total)
            self._next = k
            self._trim()
        self.compute_s += time.thread_time() - t0
        return out

    def _frames(self, ready: list[int], total: int) -> list[StreamTarget]:
        self._apply_pending_policy()
        fs = self.fs_hz
        starts = np.asarray(ready, dtype=np.int64) * self._n_hop
        speech = self._detector.windows_are_speech(self._speech.features(), starts / fs,
                                                   (starts + self._n_win) / fs)
        frames = self.pipeline.estimate_windows(self._buf, self._buf_start, starts, speech,
                                                self._stft)
        out = []
        for start, frame in zip(starts.tolist(), frames, strict=True):
            end = start + self._n_win
            if self.head_poses is not None:
                frame = self._to_base(frame, start, end)
            if self.keep_frames:
                self.frames.append(frame)
            point = self._step(frame)
            target = self._target(frame, point, min(total, end + self.lookahead) / fs)
            with self._lock:
                self._latest = target
            out.append(target)
        return out

    def _window(self, lo: int, hi: int) -> FloatArray:
        lo = max(lo, 0)
        return self._buf[:, lo - self._buf_start : hi - self._buf_start]

    def _to_base(self, frame: FrameEstimate, start: int, end: int) -> FrameEstimate:
        """A head-frame estimate in the base frame (the head's rotation over each window)."""
        fs, poses = self.fs_hz, self.head_poses
        assert poses is not None
        short = window_motion(poses, self._window(start, end), start / fs, end / fs)
        fine = None
        if frame.fine_azimuth_rad is not None:
            lo = max(0, end - self._n_fine)
            fine = window_motion(poses, self._window(lo, end), lo / fs, end / fs)
        return frame_to_base(frame, short, fine, self.max_head_sweep_rad, map_grids(self.pipeline))

    def _step(self, f: FrameEstimate) -> TrackPoint:
        """One tracker step with the arguments :meth:`Pipeline.track` gives it."""
        if self._map_tracker is not None and f.power_map is not None:
            return self._map_tracker.step(f.t_s, f.power_map, f.elevation_rad, f.speech,
                                          f.confidence)
        return self._tracker.step(f.t_s, f.azimuth_rad, f.elevation_rad, f.confidence,
                                  f.speech, f.fine_azimuth_rad, self._lag_s)

    def _target(self, f: FrameEstimate, p: TrackPoint, ready_s: float) -> StreamTarget:
        current = None
        if p.talker_azimuth_rad is not None:  # she is still followed during a wide shot
            current = self._talker_id(p.talker_azimuth_rad)
            self._note_talker(current, f, p.elevation_rad)
        with self._lock:
            self._current_id, self._last_t_s = current, f.t_s
        talker_id = current if p.shot == "talker" else None
        az = p.azimuth_rad if p.shot != "none" else math.nan
        return StreamTarget(f.t_s, f.end_s, ready_s, float(az), p.elevation_rad, p.shot,
                            talker_id, p.talker_azimuth_rad, float(f.confidence), f.speech,
                            float(f.azimuth_rad))

    def _talker_id(self, azimuth_rad: float) -> int:
        """The nearest known talker direction within the separation, else a new talker."""
        with self._lock:
            if self._talkers:
                known = np.asarray([t[0] for t in self._talkers])
                diffs = np.abs(np.angle(np.exp(1j * (known - azimuth_rad))))
                i = int(np.argmin(diffs))
                if diffs[i] <= self._separation_rad:
                    self._talkers[i][0] = float(azimuth_rad)  # follow a walker
                    return i
            self._talkers.append([float(azimuth_rad), None, math.nan, -math.inf, 0.0])
            return len(self._talkers) - 1

    def _note_talker(self, talker_id: int, f: FrameEstimate, elevation_rad: float | None) -> None:
        """Her elevation, first frame, last speech and talk time after this frame (a speech
        frame counts for her when its estimate points at her: the next talker's first words,
        before the tracker takes her, are not the current one's)."""
        hop_s = self._n_hop / self.fs_hz
        with self._lock:
            entry = self._talkers[talker_id]
            if elevation_rad is not None:
                entry[1] = float(elevation_rad)
            if not math.isfinite(entry[2]):
                entry[2] = f.t_s
            off_rad = abs(math.remainder(float(f.azimuth_rad) - entry[0], 2.0 * math.pi))
            if f.speech and off_rad <= self._separation_rad:
                entry[3] = f.t_s
                entry[4] += hop_s

    def talkers(self) -> list[TalkerSeen]:
        """The talkers followed so far (thread-safe), by id."""
        with self._lock:
            current, now = self._current_id, self._last_t_s
            return [TalkerSeen(i, az, el, first, last, total,
                               i == current and now - last <= SPEAKING_HOLD_S + 1e-9)
                    for i, (az, el, first, last, total) in enumerate(self._talkers)]

    def _trim(self) -> None:
        """Forget the audio, STFT frames and speech measurements no later window needs."""
        start = self._next * self._n_hop
        if self._stft is not None:
            self._stft.forget_before(self.pipeline.first_sample_needed(start))
        self._speech.forget_before(start - self._vad_history)
        # The audio of the next window and of its long window (the head's motion over them),
        # from where their analysis starts (Pipeline.analysis_start: up to 127 samples earlier).
        keep = min(max(0, start + self._n_win - max(self._n_fine, self._n_win)),
                   self.pipeline.first_sample_needed(start))
        if keep > self._buf_start:
            self._buf = self._buf[:, keep - self._buf_start :].copy()
            self._buf_start = keep


def stream_blocks(locator: StreamingLocator, blocks: Iterable[FloatArray]) -> list[StreamTarget]:
    """Push every block, then finish: all targets in order (offline use and tests)."""
    out: list[StreamTarget] = []
    for block in blocks:
        out.extend(locator.push(block))
    out.extend(locator.finish())
    return out


class StreamTargetSource:
    """The latest streamed target as an engine target source.

    Producers call :meth:`offer` with a target and the engine time it applies from;
    ``target_at(t_s)`` returns the newest one (None before the first shot, or when it was
    offered more than ``stale_s`` of engine time ago: a stalled capture stops steering). The
    pan is the target azimuth; the tilt is the talker's elevation when the array resolves it,
    else 0 (eye level).
    """

    def __init__(self, name: str = "audio stream", stale_s: float | None = None) -> None:
        self.name = name
        self.stale_s = stale_s
        self._lock = threading.Lock()
        self._target: StreamTarget | None = None
        self._from_s = -math.inf
        self.engine_t_s = 0.0  # the last engine time seen in target_at (producers pace on it)

    def offer(self, target: StreamTarget | None, engine_t_s: float) -> None:
        """Publish ``target`` as applying from engine time ``engine_t_s`` (None clears it)."""
        with self._lock:
            self._target, self._from_s = target, engine_t_s

    def target_at(self, t_s: float) -> Target | None:
        self.engine_t_s = t_s
        with self._lock:
            target, from_s = self._target, self._from_s
        if target is None or not math.isfinite(target.azimuth_rad):
            return None
        if self.stale_s is not None and t_s - from_s > self.stale_s:
            return None
        if target.shot == "wide":
            label = "wide shot"
        elif target.talker_id is not None and target.talker_azimuth_rad is not None:
            label = f"talker {target.talker_id + 1} at {math.degrees(target.talker_azimuth_rad):+.0f}°"
        else:
            label = None
        # The tilt follows the talker's smoothed elevation when the array resolves it (a cube,
        # the seed's vertical pair); a flat array cannot, and a wide shot keeps eye level.
        tilt = target.elevation_rad if target.shot == "talker" else None
        return Target(
            pan_rad=float(target.azimuth_rad),
            tilt_rad=float(tilt) if tilt is not None else 0.0,
            talker=label,
            azimuth_rad=target.estimate_azimuth_rad if target.speech else None,
            elevation_rad=target.elevation_rad if target.speech else None,
        )
