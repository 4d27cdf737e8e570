"""The talker tracker as the engine's target source, streamed in real time on the engine clock.

The input is the ``audio_input`` setting (``TRACKER_AUDIO_INPUT``):

* ``simulated`` (default): a meeting (talkers taking turns, one walking) simulated once with the
  audio engineer's room model. Building the room audio takes tens of seconds, so it runs in a
  worker process at start-up and the multichannel audio is cached in the data folder; then it
  is streamed block by block through the localizer and the talker tracker
  (:class:`tracker.audio.stream.StreamingLocator`) paced by the engine clock, looping;
* ``wav:PATH``: a multichannel WAV file, streamed the same way (looping);
* ``live`` or ``live:DEVICE``: the sound card (PortAudio via sounddevice,
  :class:`tracker.audio.capture.LiveCapture`): opened at its own rate (or
  ``audio_device_rate_hz``) and resampled to 16 kHz, the array's mics picked from its channels
  by ``audio_channel_map``. When PortAudio is missing the status says why (``audio`` field);
  when the device is missing or disappears the status shows the fault (``audio_capture``) and
  capture retries with back-off until it returns; the console keeps manual pointing.

The array is the ``array_file`` setting (default: the shipped 4-mic square); the simulated
meeting is rendered for it. A head-mounted array (``"mount": "head"``) works with live capture:
each block carries the engine's measured pan and tilt, and the stream turns every window's
estimate into the base frame with the head's rotation over that window. The simulated meeting
and a WAV replay cannot follow the head (their audio does not turn with it), so with a
head-mounted array they say so in the status instead of steering the camera wrongly.

The localizer runs in a background thread (a block batch at a time), never on the event loop.
Until the first shot the source says nothing and the engine holds. :class:`MeetingSource`
(the batch replay of a :class:`TrackTable`) is kept as the offline reference.
"""

from __future__ import annotations

import logging
import math
import os
import threading
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from tracker.resources import project_dir
from tracker.targets import Target

if TYPE_CHECKING:
    from tracker.audio.array import MicArray
    from tracker.audio.pipeline import Pipeline
    from tracker.audio.policy import CameraPolicy

log = logging.getLogger("app.audio")
FloatArray = NDArray[np.float64]
CACHE_VERSION = 1
AUDIO_CACHE_VERSION = 1
BLOCK_S = 0.1  # streaming block
MAX_BATCH_BLOCKS = 10  # at most this many blocks per push when catching up with the engine
ARRAYS_DIR = project_dir("examples") / "arrays"


@dataclass(frozen=True, slots=True)
class TrackTable:
    """The tracked meeting: per analysis window, when it is available and what it says.

    Arrays have shape (n_windows,): ``end_s`` (s, increasing), ``target_az_rad`` (camera
    target; NaN = no shot yet), ``talker_az_rad`` (the talker the tracker follows; NaN = wide
    shot or none), ``estimate_az_rad`` / ``estimate_el_rad`` (the localizer's raw estimate; NaN
    outside speech). ``duration_s`` is the loop length.
    """

    end_s: FloatArray
    target_az_rad: FloatArray
    talker_az_rad: FloatArray
    estimate_az_rad: FloatArray
    estimate_el_rad: FloatArray
    duration_s: float

    def save(self, path: Path) -> None:
        tmp = path.with_name(path.name + ".part.npz")
        np.savez(
            tmp,
            version=CACHE_VERSION,
            end_s=self.end_s,
            target_az_rad=self.target_az_rad,
            talker_az_rad=self.talker_az_rad,
            estimate_az_rad=self.estimate_az_rad,
            estimate_el_rad=self.estimate_el_rad,
            duration_s=self.duration_s,
        )
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path) -> TrackTable | None:
        try:
            d = np.load(path)
            if int(d["version"]) != CACHE_VERSION:
                return None
            return cls(
                d["end_s"],
                d["target_az_rad"],
                d["talker_az_rad"],
                d["estimate_az_rad"],
                d["estimate_el_rad"],
                float(d["duration_s"]),
            )
        except (OSError, KeyError, ValueError):
            return None


class MeetingSource:
    """A target source (``name``, ``target_at``) replaying a tracked meeting on engine time."""

    def __init__(self, table: TrackTable | None = None, name: str = "simulated meeting") -> None:
        self.name = name
        self.table = table
        self.note = "ready" if table is not None else "preparing the simulated meeting"
        self.worker: Any = None  # the subprocess building the meeting, while it runs
        self.closed = False

    def close(self) -> None:
        """Stop building the meeting (at shutdown)."""
        self.closed = True
        proc = self.worker
        if proc is not None and proc.poll() is None:
            proc.terminate()

    def target_at(self, t_s: float) -> Target | None:
        """The tracker's target at engine time ``t_s`` (looping), or None before the first shot."""
        tab = self.table
        if tab is None:
            return None
        t = t_s % tab.duration_s
        i = int(np.searchsorted(tab.end_s, t, side="right")) - 1
        if i < 0 or not math.isfinite(tab.target_az_rad[i]):
            return None
        talker = tab.talker_az_rad[i]
        label = f"talker at {math.degrees(talker):+.0f}°" if math.isfinite(talker) else "wide shot"
        est_az, est_el = tab.estimate_az_rad[i], tab.estimate_el_rad[i]
        return Target(
            pan_rad=float(tab.target_az_rad[i]),
            tilt_rad=0.0,  # the planar array cannot resolve elevation; the camera keeps eye level
            talker=label,
            azimuth_rad=float(est_az) if math.isfinite(est_az) else None,
            elevation_rad=float(est_el) if math.isfinite(est_el) else None,
        )


def load_meeting_array(array_file: Path | str | None = None) -> MicArray:
    """The configured array (``array_file`` setting), or the meeting's shipped one."""
    from tracker.audio.array import load_array
    from tracker.scenarios.meeting import MeetingSettings

    return load_array(array_file if array_file is not None
                      else ARRAYS_DIR / MeetingSettings().array_file)


def meeting_pipeline(fs_hz: int, array: Any = None, policy: CameraPolicy | None = None) -> Pipeline:
    """The meeting's localizer, windows and tracker settings for audio at ``fs_hz``, the
    trackers framing talkers with the camera-operator ``policy`` (their defaults when None).

    The camera and its head sit on the wall, so talkers are in -90°..90° of the base frame
    (no mirror image of the wall), within the array file's field of view, and the map tracker
    frames them over that range. A room-mounted array under the camera searches just that
    range; a head-mounted one turns away from the wall with the camera, so it searches every
    azimuth of its own frame and each window's map is turned into the base range with the
    head's angles.
    """
    from tracker.audio.pipeline import Pipeline, choose_tracker
    from tracker.scenarios.meeting import MeetingSettings

    settings = MeetingSettings()
    array = array if array is not None else load_meeting_array()
    room_range = array.field_of_view.narrowed((-np.pi / 2, np.pi / 2), array.name).azimuth_rad
    options = {} if array.head_mounted else {"azimuth_range_rad": room_range}
    tracking, map_tracking = settings.tracking, settings.map_tracking
    if policy is not None:
        tracking, map_tracking = policy.apply(tracking), policy.apply(map_tracking)
    return Pipeline(array, fs_hz, settings.method, settings.windows, tracking=tracking,
                    localizer_options=options,
                    tracker=choose_tracker(settings.method),
                    map_tracking=map_tracking,
                    base_azimuth_range_rad=room_range if array.head_mounted else None)


def build_meeting_audio(seed: int, duration_s: float, array_file: Path | str | None = None
                        ) -> tuple[int, FloatArray]:
    """The simulated meeting's multichannel audio (tens of seconds of CPU): (fs_hz, (n_mics, n))."""
    from tracker.scenarios.meeting import MeetingSettings, build_meeting

    recording, _ = build_meeting(seed, duration_s, MeetingSettings(), load_meeting_array(array_file))
    return int(recording.fs_hz), np.asarray(recording.audio, dtype=float)


def save_audio(path: Path, fs_hz: int, audio: FloatArray) -> None:
    tmp = path.with_name(path.name + ".part.npz")
    np.savez(tmp, version=AUDIO_CACHE_VERSION, fs_hz=fs_hz, audio=audio.astype(np.float32))
    tmp.replace(path)


def load_audio(path: Path) -> tuple[int, FloatArray] | None:
    try:
        d = np.load(path)
        if int(d["version"]) != AUDIO_CACHE_VERSION:
            return None
        return int(d["fs_hz"]), np.asarray(d["audio"], dtype=float)
    except (OSError, KeyError, ValueError):
        return None


def settings_digest(array: MicArray | None = None) -> str:
    """A short digest of the meeting settings and the array's geometry: a cache made with
    others is not reused."""
    import hashlib

    from tracker.scenarios.meeting import MeetingSettings

    mics = "" if array is None else np.round(array.positions_m, 6).tobytes().hex()
    text = f"{AUDIO_CACHE_VERSION}:{MeetingSettings()!r}:{mics}"
    return hashlib.sha256(text.encode()).hexdigest()[:10]


class AudioStream:
    """Streams an input through :class:`~tracker.audio.stream.StreamingLocator` in a thread.

    ``source`` is the engine's target source; ``note`` the status line ("ready", "preparing
    ...", or why audio is unavailable); ``cpu_ms_per_s`` the localizer's CPU per second of audio.
    """

    def __init__(self, engine: Any, label: str, array: MicArray | None = None,
                 policy: CameraPolicy | None = None) -> None:
        from tracker.audio.policy import CameraPolicy
        from tracker.audio.stream import StreamTargetSource

        self.engine = engine
        self.array = array if array is not None else load_meeting_array()
        self.policy = policy if policy is not None else CameraPolicy()
        self.source = StreamTargetSource(name=label, stale_s=2.0)
        self.note = "starting"
        self.worker: Any = None  # the subprocess building the meeting audio, while it runs
        self.locator: Any = None
        self.closed = False
        self._stop = threading.Event()
        self.live: Any = None  # live capture, while listening
        self._thread: threading.Thread | None = None
        self._cpu_s = 0.0
        self._audio_s = 0.0

    @property
    def dropped_blocks(self) -> int:
        """Live input blocks lost: flagged by the card (overflow) or too late for the localizer
        (0 for a file or the simulated room, which wait for the localizer)."""
        live = self.live
        return int(getattr(live, "overflows", 0)) + int(getattr(live, "dropped_blocks", 0))

    @property
    def cpu_ms_per_s(self) -> float:
        loc = self.locator
        cpu = self._cpu_s + (loc.compute_s if loc is not None else 0.0)
        audio = self._audio_s + (loc.samples_in / loc.fs_hz if loc is not None else 0.0)
        return 1000.0 * cpu / audio if audio > 0 else math.nan

    def start(self, work: Any) -> None:
        def run() -> None:
            try:
                work()
            except Exception as exc:  # the console must keep working with manual pointing
                if not self.closed:
                    self.note = f"audio stopped: {type(exc).__name__}: {exc}"
                    log.exception("the audio stream stopped")

        self._thread = threading.Thread(target=run, name="audio-stream", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop streaming (at shutdown)."""
        self.closed = True
        self._stop.set()
        live = self.live
        if live is not None:  # wakes a capture waiting for its device
            live.close()
        proc = self.worker
        if proc is not None and proc.poll() is None:
            proc.terminate()

    def set_policy(self, policy: CameraPolicy) -> None:
        """Frame talkers with ``policy`` from the stream's next frame on (and in every later
        loop or reconnection): no restart, the tracker keeps its talkers."""
        self.policy = policy
        loc = self.locator
        if loc is not None:
            loc.set_policy(policy)

    def engine_time_s(self) -> float:
        return float(self.engine.status().t_s)

    def _new_locator(self, fs_hz: int, n_channels: int) -> Any:
        from tracker.audio.stream import StreamingLocator
        from tracker.errors import DataError

        pipeline = meeting_pipeline(fs_hz, self.array, self.policy)
        if n_channels != pipeline.array.n_mics:
            raise DataError(f"the input has {n_channels} channel(s) but {pipeline.array.name} "
                            f"has {pipeline.array.n_mics} mics")
        if self.locator is not None:
            self._cpu_s += self.locator.compute_s
            self._audio_s += self.locator.samples_in / self.locator.fs_hz
        self.locator = StreamingLocator(pipeline)
        self.locator.set_policy(self.policy)  # a policy set while this one was being built
        return self.locator

    def play(self, fs_hz: int, audio: FloatArray) -> None:
        """Stream ``audio`` (n_channels, n) on the engine clock, looping, until closed."""
        n = audio.shape[1]
        block = max(1, int(round(BLOCK_S * fs_hz)))
        while not self._stop.is_set():
            loc = self._new_locator(fs_hz, audio.shape[0])
            t0, pos = self.engine_time_s(), 0
            while pos < n and not self._stop.is_set():
                due = int((self.engine_time_s() - t0) * fs_hz)
                if due - pos < block and due < n:
                    self._stop.wait(0.02)
                    continue
                hi = min(n, due, pos + MAX_BATCH_BLOCKS * block)
                for target in loc.push(audio[:, pos:hi]):
                    self.source.offer(target, t0 + target.ready_s)
                pos = hi
            for target in loc.finish():
                self.source.offer(target, t0 + target.ready_s)

    def listen(self, live: Any) -> None:
        """Stream live capture until closed (the device paces it).

        When the device comes back after a fault (``live.generation`` changes) the stream starts
        a new locator: the audio before and after the gap share no clock. With a head-mounted
        array every block carries the engine's measured pan and tilt at the moment it arrived
        (:meth:`_record_head`).
        """
        self.live = live
        try:
            generation = None
            loc: Any = None
            arrivals: deque[float] = deque(maxlen=50)  # engine time minus stream time, 5 s
            for block in live.blocks(BLOCK_S):
                if self._stop.is_set():
                    break
                if loc is None or getattr(live, "generation", 0) != generation:
                    generation = getattr(live, "generation", 0)
                    loc = self._new_locator(live.fs_hz, live.n_channels)
                    arrivals.clear()
                if loc.head_poses is not None:
                    self._record_head(loc, block.shape[1], arrivals)
                for target in loc.push(block):
                    self.source.offer(target, self.engine_time_s())
        finally:
            live.close()

    def talkers_state(self) -> list[dict[str, Any]]:
        """The talkers the stream has followed, in degrees, ``last_spoken_ago_s`` counted from
        the newest frame (None if she never spoke while followed)."""
        loc = self.locator
        if loc is None:
            return []
        latest = loc.latest
        now = latest.t_s if latest is not None else 0.0
        out = []
        for t in loc.talkers():
            spoke = math.isfinite(t.last_spoken_s)
            out.append({
                "talker_id": t.talker_id,
                "azimuth_deg": round(math.degrees(t.azimuth_rad), 2),
                "elevation_deg": None if t.elevation_rad is None else round(math.degrees(t.elevation_rad), 2),
                "speaking": t.speaking,
                "last_spoken_ago_s": round(max(0.0, now - t.last_spoken_s), 2) if spoke else None,
                "speaking_s": round(t.speaking_s, 2),
            })
        return out

    def capture_state(self) -> dict[str, Any] | None:
        """Live capture's status (device, rates, channel map, counts, fault), or None."""
        status = getattr(self.live, "status", None)
        if status is None:
            return None
        import dataclasses

        out: dict[str, Any] = dataclasses.asdict(status())
        out["channel_map"] = list(out["channel_map"])
        return out

    def _record_head(self, loc: Any, n_block: int, arrivals: deque[float]) -> None:
        """Add the engine's pan/tilt now, time-stamped on the stream's clock.

        A block arrives a little after its last sample was captured; the smallest arrival
        delay of the last 5 s of blocks aligns the two clocks (it also follows the sound
        card's clock drifting from the engine's), so a reading taken as block k arrives is
        stamped at about the stream time it belongs to.
        """
        status = self.engine.status()
        end_s = (loc.samples_in + n_block) / loc.fs_hz
        arrivals.append(status.t_s - end_s)
        t_s = status.t_s - min(arrivals)
        span = loc.head_poses.span_s
        if span is None or t_s > span[1]:
            loc.head_poses.add(t_s, status.pan_rad, status.tilt_rad)


def parse_input(value: str | None) -> tuple[str, str | None]:
    """The audio input setting (``TRACKER_AUDIO_INPUT`` when not given), validated."""
    from app.settings import parse_audio_input
    from tracker.errors import ConfigError

    value = value if value is not None else os.environ.get("TRACKER_AUDIO_INPUT", "simulated")
    try:
        return parse_audio_input(value)
    except ValueError as exc:
        raise ConfigError(f"setting 'audio_input': {exc}") from None


def start_meeting_source(engine: Any, cache_dir: Path, seed: int = 1, duration_s: float = 60.0,
                         audio_input: str | None = None, array_file: Path | str | None = None,
                         policy: CameraPolicy | None = None, capture: Any = None) -> AudioStream:
    """Plug the streamed talker tracker into ``engine`` now and start streaming ``audio_input``
    heard by the array of ``array_file`` (default: the shipped 4-mic square), the camera
    framing talkers with ``policy``; live input opens the sound card with ``capture`` (a
    :class:`~tracker.audio.capture.CaptureSettings`; the device's defaults when None).

    Problems opening the input (PortAudio missing, a WAV with the wrong channel count, a
    head-mounted array on an input that cannot follow the head) end up in the returned
    handle's ``note``; they never raise. A bad array file raises ConfigError (the service
    checks it before it starts).
    """
    kind, arg = parse_input(audio_input)
    array = load_meeting_array(array_file)
    if kind == "live":
        return _start_live(engine, arg, array, policy, capture)
    if kind == "wav":
        return _start_wav(engine, Path(str(arg)), array, policy)
    stream = AudioStream(engine, "simulated meeting", array, policy)
    engine.set_target_source(stream.source)
    if array.head_mounted:
        stream.note = (f"audio unavailable: {array.name} is head-mounted and the simulated "
                       "meeting holds the array still in the room; use live input")
        return stream
    stream.note = "preparing the simulated meeting"
    digest = settings_digest(array if array_file is not None else None)
    cache = cache_dir / f"meeting_audio_seed{seed}_{int(duration_s)}s_{digest}.npz"

    def work() -> None:
        loaded = load_audio(cache) if cache.exists() else None
        if loaded is None:
            loaded = _build_in_worker(stream, seed, duration_s, cache, array_file)
            if loaded is None:
                return
        stream.note = "ready"
        log.info("simulated meeting ready: streaming %.0f s of audio", loaded[1].shape[1] / loaded[0])
        stream.play(*loaded)

    stream.start(work)
    return stream


def _build_in_worker(stream: AudioStream, seed: int, duration_s: float, cache: Path,
                     array_file: Path | str | None = None) -> tuple[int, FloatArray] | None:
    # In a separate process: the room simulation would otherwise hold the GIL for long
    # stretches and make the engine loop (same process) miss its real-time pace.
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "app.audio", str(seed), str(duration_s), str(cache)]
    if array_file is not None:
        cmd.append(str(Path(array_file).resolve()))
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            cwd=Path(__file__).resolve().parent.parent)
    stream.worker = proc
    _, err = proc.communicate(timeout=900)
    stream.worker = None
    if stream.closed:
        return None
    if proc.returncode != 0:
        tail = err.strip().splitlines()
        raise RuntimeError(tail[-1] if tail else f"worker exited with {proc.returncode}")
    loaded = load_audio(cache)
    if loaded is None:
        raise RuntimeError(f"the meeting audio was not written to {cache}")
    return loaded


def _start_wav(engine: Any, path: Path, array: MicArray, policy: CameraPolicy | None = None
               ) -> AudioStream:
    from tracker.audio.sources import read_wav
    from tracker.errors import TrackerError

    stream = AudioStream(engine, f"wav {path.name}", array, policy)
    engine.set_target_source(stream.source)
    if array.head_mounted:
        stream.note = (f"audio unavailable: {array.name} is head-mounted and a WAV replay "
                       "cannot follow the head: use live input, `tracker audio locate --encoder` "
                       'offline, or "mount": "room" if the head did not move while recording')
        return stream
    try:
        fs_hz, audio = read_wav(path)
        stream._new_locator(fs_hz, audio.shape[0])  # channel count checked before streaming
    except TrackerError as exc:
        stream.note = f"audio unavailable: {exc}"
        return stream
    stream.note = "ready"
    stream.start(lambda: stream.play(fs_hz, audio))
    return stream


def _start_live(engine: Any, device: str | None, array: MicArray,
                policy: CameraPolicy | None = None, capture: Any = None) -> AudioStream:
    from tracker.audio import capture as live_capture
    from tracker.errors import TrackerError

    stream = AudioStream(engine, "live capture", array, policy)
    engine.set_target_source(stream.source)
    if capture is None:
        dev: int | str | None = int(device) if device is not None and device.isdigit() else device
        capture = live_capture.CaptureSettings(device=dev)
    try:
        live = live_capture.LiveCapture(array.n_mics, capture)
    except TrackerError as exc:  # PortAudio missing, a channel map that does not fit: say why
        stream.note = f"live capture unavailable: {exc}"
        log.error("live capture unavailable: %s", exc)
        return stream
    stream.live = live
    stream.note = "ready"
    stream.start(lambda: stream.listen(live))
    return stream


if __name__ == "__main__":  # the worker: python -m app.audio SEED DURATION_S OUT.npz [ARRAY.json]
    import sys

    array_arg = sys.argv[4] if len(sys.argv) > 4 else None
    save_audio(Path(sys.argv[3]), *build_meeting_audio(int(sys.argv[1]), float(sys.argv[2]),
                                                       array_arg))
