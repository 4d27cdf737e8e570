"""The audio input setting: simulated / live / wav:PATH, streamed on the engine clock."""

from __future__ import annotations

import asyncio
import math
import time
from pathlib import Path

import numpy as np
import pytest

from app.audio import AudioStream, start_meeting_source
from app.settings import load_settings
from tests.tracker.audio.conftest import FS_HZ, example_array, free_field
from tracker.audio.sources import write_wav
from tracker.errors import ConfigError, DriverFault

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
    import tracker.audio.sources as sources

    def missing() -> None:
        raise DriverFault("live capture needs the PortAudio library (not found); "
                          "install it with: apt-get install libportaudio2")

    monkeypatch.setattr(sources, "_sounddevice", missing)
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
    # CPU of the streaming localizer, ms per s of audio: far below real time.
    assert stream.cpu_ms_per_s < 500.0


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
