"""The audio input setting: simulated / live / wav:PATH, streamed on the engine clock."""

from __future__ import annotations

import asyncio
import json
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import app.audio as app_audio
from app.audio import AudioStream, start_meeting_source
from app.settings import load_settings
from tests.tracker.audio.conftest import ARRAYS_DIR, FS_HZ, example_array, free_field
from tracker.audio.array import rotation_world_head, unit_vector
from tracker.audio.sources import write_wav
from tracker.audio.speech import synthetic_speech
from tracker.errors import ConfigError, DriverFault
from tracker.units import SPEED_OF_SOUND_M_PER_S

TALKER_1_DEG, TALKER_2_DEG = 35.0, -40.0


@pytest.mark.parametrize(
    ("value", "words"),
    [("mic", ["audio_input", "TRACKER_AUDIO_INPUT", "'mic'", "simulated"]),
     ("wav:", ["audio_input", "needs a file path"]),
     ("wav:/no/such/file.wav", ["audio_input", "/no/such/file.wav", "not found"])],
)
def test_a_bad_audio_input_is_a_config_error_at_startup(
        monkeypatch: pytest.MonkeyPatch, value: str, words: list[str]) -> None:
    monkeypatch.setenv("TRACKER_AUDIO_INPUT", value)
    with pytest.raises(ConfigError) as err:
        load_settings(None)
    for word in words:
        assert word in str(err.value)


def test_good_audio_inputs_are_accepted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert load_settings(None).audio_input == "simulated"
    wav = tmp_path / "a.wav"
    write_wav(wav, FS_HZ, np.zeros((4, 100)))
    for value in ("live", "live:2", f"wav:{wav}", "simulated"):
        monkeypatch.setenv("TRACKER_AUDIO_INPUT", value)
        assert load_settings(None).audio_input == value


class _Engine:
    """Just the engine parts the audio stream uses (the real engine is tested below)."""

    def __init__(self) -> None:
        self.source = None

    def set_target_source(self, source: object) -> None:
        self.source = source


def test_live_without_portaudio_says_why_and_does_not_crash(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import tracker.audio.capture as capture

    def missing() -> None:
        raise DriverFault("live capture needs the PortAudio library (not found); "
                          "install it with: apt-get install libportaudio2")

    monkeypatch.setattr(capture, "sounddevice_backend", missing)
    engine = _Engine()
    stream = start_meeting_source(engine, tmp_path, audio_input="live")
    assert "live capture unavailable" in stream.note and "PortAudio" in stream.note
    assert engine.source is stream.source and stream.source.target_at(1.0) is None
    stream.close()


def two_talkers_wav(path: Path, n_mics_array: str = "square4_65mm") -> None:
    array = example_array(n_mics_array)
    rng = np.random.default_rng(3)
    gap = 0.001 * rng.standard_normal((array.n_mics, FS_HZ // 2))
    a = free_field(array, math.radians(TALKER_1_DEG), duration_s=3.0, seed=1)
    b = free_field(array, math.radians(TALKER_2_DEG), duration_s=3.0, seed=2)
    write_wav(path, FS_HZ, np.concatenate([gap, a, gap, b, gap], axis=1))


def test_a_wav_with_the_wrong_channel_count_says_so(tmp_path: Path) -> None:
    path = tmp_path / "stereo.wav"
    write_wav(path, FS_HZ, 0.1 * np.random.default_rng(0).standard_normal((2, FS_HZ)))
    stream = start_meeting_source(_Engine(), tmp_path, audio_input=f"wav:{path}")
    assert "2 channel" in stream.note and "4 mics" in stream.note


def test_the_engine_follows_a_wav_streamed_on_its_clock(tmp_path: Path) -> None:
    from tracker.drivers.sim import SimDriver
    from tracker.engine import Engine

    path = tmp_path / "meeting.wav"
    two_talkers_wav(path)
    engine = Engine(SimDriver())
    engine.set_tracking(True)
    stream = start_meeting_source(engine, tmp_path, audio_input=f"wav:{path}")
    assert isinstance(stream, AudioStream) and stream.note == "ready"
    seen: dict[float, float] = {}
    # The stream counts engine time from when its thread starts: let it start before the engine
    # moves (on a busy machine it started at 0.25 s and this test then waited 28 × 20 s).
    deadline = time.monotonic() + 20
    while stream.locator is None and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.2)
    try:
        for _ in range(28):  # 7 s of engine time (the WAV is 7.5 s) in 0.25 s steps
            asyncio.run(engine.run(realtime=False, duration_s=0.25))
            t = engine.status().t_s
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                loc = stream.locator
                if loc is not None and loc.samples_in >= (t - 0.2) * FS_HZ:
                    break
                time.sleep(0.01)
            seen[t] = math.degrees(engine.status().pan_rad)
    finally:
        stream.close()
    st = engine.status()
    assert st.mode == "tracking" and st.active_talker is not None
    assert "talker" in st.active_talker
    # Talker 1 had the camera by 3.5 s, talker 2 at the end (the camera follows the stream).
    at_3_5 = seen[min(seen, key=lambda t: abs(t - 3.5))]
    assert abs(at_3_5 - TALKER_1_DEG) < 5.0, seen
    assert abs(math.degrees(st.pan_rad) - TALKER_2_DEG) < 5.0, seen
    # The stream reports its CPU cost (ms per s of audio). How small it is is a figure for
    # bench/bench_stream.py, not a timed test: here it includes numba's first compilation.
    assert math.isfinite(stream.cpu_ms_per_s) and stream.cpu_ms_per_s > 0.0


def test_the_configured_audio_input_reaches_the_stream(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Regression: app.rig started the audio with only the data folder, so a config-file
    ``audio_input`` was validated but never used."""
    import app.audio
    from app.rig import attach_audio

    wav = tmp_path / "room.wav"
    two_talkers_wav(wav)
    settings = load_settings(None, data_dir=tmp_path, audio_input=f"wav:{wav}")
    seen: dict[str, object] = {}
    monkeypatch.setattr(app.audio, "start_meeting_source", lambda *a, **kw: seen.update(kw) or "handle")
    assert attach_audio(object(), settings) == ("handle", None)
    assert seen["audio_input"] == f"wav:{wav}"
    assert seen["array_file"] is None  # the shipped square


def test_the_configured_array_file_reaches_the_stream(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Regression: the stream always used the shipped 4-mic square, whatever ``array_file``
    said (a 6-mic recording was refused as having the wrong channel count)."""
    import app.audio
    from app.rig import attach_audio

    six = ARRAYS_DIR / "circular6_46mm.json"
    settings = load_settings(None, data_dir=tmp_path, array_file=six)
    seen: dict[str, object] = {}
    monkeypatch.setattr(app.audio, "start_meeting_source", lambda *a, **kw: seen.update(kw) or "handle")
    attach_audio(object(), settings)
    assert seen["array_file"] == six
    monkeypatch.undo()
    from tracker.drivers.sim import SimDriver
    from tracker.engine import Engine

    wav = tmp_path / "six.wav"
    two_talkers_wav(wav, "circular6_46mm")
    stream = start_meeting_source(Engine(SimDriver()), tmp_path, audio_input=f"wav:{wav}",
                                  array_file=six)
    try:
        assert stream.note == "ready", stream.note
        assert stream.array.n_mics == 6 and stream.array.name == str(six)
    finally:
        stream.close()


def test_the_simulated_meeting_is_rendered_for_the_configured_array(tmp_path: Path) -> None:
    from tracker.drivers.sim import SimDriver
    from tracker.engine import Engine

    six = ARRAYS_DIR / "circular6_46mm.json"
    stream = start_meeting_source(Engine(SimDriver()), tmp_path, duration_s=3.0,
                                  audio_input="simulated", array_file=six)
    try:
        deadline = time.monotonic() + 60
        while stream.locator is None and time.monotonic() < deadline and "stopped" not in stream.note:
            time.sleep(0.05)
        assert stream.locator is not None, stream.note
        assert stream.locator.pipeline.array.n_mics == 6 and stream.note == "ready"
    finally:
        stream.close()
    cached = list(tmp_path.glob("meeting_audio_*.npz"))
    assert len(cached) == 1 and app_audio.settings_digest() not in cached[0].name


def head_square(tmp_path: Path) -> Path:
    path = tmp_path / "head_square.json"
    path.write_text(json.dumps({"mics": example_array("square4_65mm").positions_m.tolist(),
                                "mount": "head"}))
    return path


@pytest.mark.parametrize("audio_input", ["simulated", "wav"])
def test_inputs_that_cannot_follow_the_head_say_so(tmp_path: Path, audio_input: str) -> None:
    wav = tmp_path / "room.wav"
    write_wav(wav, FS_HZ, 0.1 * np.random.default_rng(0).standard_normal((4, FS_HZ)))
    value = f"wav:{wav}" if audio_input == "wav" else "simulated"
    engine = _Engine()
    stream = start_meeting_source(engine, tmp_path, audio_input=value, array_file=head_square(tmp_path))
    assert "head_square.json is head-mounted" in stream.note and "live" in stream.note
    assert engine.source is stream.source and stream.source.target_at(1.0) is None
    assert stream.locator is None  # nothing streams, nothing steers


class _HeadMountedCapture:
    """Live capture from a head-mounted array, closed around the engine: a talker stands at
    ``talker_deg`` in the base frame and each block is rendered (exact plane-wave delays) from
    her direction in the head frame at the engine's pan and tilt when the block is released."""

    def __init__(self, engine: Any, array: Any, talker_deg: float, duration_s: float) -> None:
        self.engine, self.array = engine, array
        self.fs_hz, self.n_channels = FS_HZ, array.n_mics
        speech = synthetic_speech(duration_s, FS_HZ, seed=6).samples
        self.n = speech.size
        self.spectrum = np.fft.rfft(speech, 2 * self.n)
        self.freqs = np.fft.rfftfreq(2 * self.n, 1.0 / FS_HZ)
        self.talker_rad = math.radians(talker_deg)
        self.noise = 0.01 * float(np.std(speech)) * np.random.default_rng(7).standard_normal(
            (array.n_mics, self.n))
        self.closed = False

    def blocks(self, block_s: float) -> Iterator[np.ndarray]:
        n_block = int(round(block_s * FS_HZ))
        for k in range(self.n // n_block):
            deadline = time.monotonic() + 3.0  # the engine stopped for good: the capture ends
            while self.engine.status().t_s < (k + 1) * block_s:
                if time.monotonic() > deadline:
                    return
                time.sleep(0.002)
            st = self.engine.status()
            u_head = rotation_world_head(st.pan_rad, st.tilt_rad).T @ unit_vector(self.talker_rad, 0.0)
            arrival_s = -(self.array.positions_m @ u_head) / SPEED_OF_SOUND_M_PER_S
            audio = np.fft.irfft(self.spectrum[None, :] * np.exp(
                -2j * np.pi * self.freqs[None, :] * arrival_s[:, None]), 2 * self.n)
            lo = k * n_block
            yield audio[:, lo : lo + n_block] + self.noise[:, lo : lo + n_block]

    def close(self) -> None:
        self.closed = True


def test_the_meeting_pipeline_takes_the_map_tracker_for_both_mounts(tmp_path: Path) -> None:
    """Room-mounted: maps steered over the wall's front half. Head-mounted: every head-frame
    azimuth steered, each map turned onto the base frame's front half."""
    from tracker.audio.array import load_array

    room_pipeline = app_audio.meeting_pipeline(FS_HZ, example_array("square4_65mm"))
    head_pipeline = app_audio.meeting_pipeline(FS_HZ, load_array(head_square(tmp_path)))
    assert room_pipeline.tracker == head_pipeline.tracker == "map"
    assert room_pipeline.steer_azimuth_rad.size == room_pipeline.map_azimuth_rad.size == 181
    assert head_pipeline.steer_azimuth_rad.size == 360 and head_pipeline.map_azimuth_rad.size == 181
    assert math.degrees(head_pipeline.map_azimuth_rad[0]) == pytest.approx(-90.0)


def test_a_head_mounted_array_steers_the_camera_in_the_base_frame(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Closed loop: the head turns toward the talker, the array turns with it, and the engine's
    pan/tilt fed to the stream keep her at 35° in the base frame (the map tracker, each window's
    map turned with the head). Without them the loop would settle at 17.5° (the head-frame
    estimate 35° - pan taken as the target)."""
    import tracker.audio.capture as capture
    from tracker.audio.array import load_array
    from tracker.drivers.sim import SimDriver
    from tracker.engine import Engine

    array = load_array(head_square(tmp_path))
    engine = Engine(SimDriver())
    engine.set_tracking(True)
    captures: list[_HeadMountedCapture] = []

    def live(n_mics: int, settings: capture.CaptureSettings) -> _HeadMountedCapture:
        assert n_mics == 4 and settings.pipeline_rate_hz == FS_HZ
        captures.append(_HeadMountedCapture(engine, array, 35.0, 7.0))
        return captures[-1]

    monkeypatch.setattr(capture, "LiveCapture", live)
    stream = start_meeting_source(engine, tmp_path, audio_input="live", array_file=array.name)
    assert stream.note == "ready", stream.note
    pans: dict[float, float] = {}
    try:
        for _ in range(65):  # 6.5 s of engine time in 0.1 s steps, waiting for the audio each time
            asyncio.run(engine.run(realtime=False, duration_s=0.1))
            t = engine.status().t_s
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                loc = stream.locator
                if loc is not None and loc.samples_in >= (t - 0.15) * FS_HZ:
                    break
                time.sleep(0.005)
            pans[round(t, 2)] = math.degrees(engine.status().pan_rad)
    finally:
        stream.close()
    assert stream.locator is not None and stream.locator.head_poses is not None
    assert stream.locator.pipeline.tracker == "map"
    assert len(stream.locator.head_poses) > 30  # one reading per block
    st = engine.status()
    assert st.mode == "tracking" and st.active_talker is not None and "+35°" in st.active_talker
    late = [p for t, p in pans.items() if t > 4.0]
    assert max(abs(p - 35.0) for p in late) < 4.0, pans
    deadline = time.monotonic() + 10
    while not captures[0].closed and time.monotonic() < deadline:
        time.sleep(0.01)
    assert captures[0].closed  # the stream closes the device when it stops

