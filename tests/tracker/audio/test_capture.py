"""Live capture through the sounddevice callback path (a fake device the test drives): rates,
channel map, overflow and drop counts, the device leaving and coming back, the device list."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracker.audio.conftest import FS_HZ, angle_error_deg
from tests.tracker.audio.fake_sounddevice import FakeBackend, device_frames, plane_wave
from tracker.audio.array import MicArray
from tracker.audio.capture import CaptureSettings, LiveCapture, list_input_devices
from tracker.audio.pipeline import Pipeline, WindowSettings
from tracker.audio.stream import StreamingLocator
from tracker.errors import ConfigError, DriverFault


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def locator(array: MicArray) -> StreamingLocator:
    return StreamingLocator(Pipeline(array, FS_HZ, "srp_phat", WindowSettings(0.3, 0.1, 1.5),
                                     localizer_options={"azimuth_range_rad": (-math.pi / 2, math.pi / 2)}))


@pytest.mark.parametrize("rate_hz", [48000, 44100, 16000], ids=["48k", "44.1k", "16k"])
def test_a_talker_heard_through_the_card_at_any_rate_is_located(square4: MicArray, rate_hz: int
                                                                ) -> None:
    """Speech from 35° at the card's rate, the array's mics on device channels 5, 2, 0, 3 of 6,
    delivered in 1000-frame blocks: resampled to 16 kHz and mapped, the localizer finds 35°."""
    channel_map = (5, 2, 0, 3)
    backend = FakeBackend(channels=6, rate_hz=rate_hz)
    clock = Clock()
    capture = LiveCapture(4, CaptureSettings(device="USB", channel_map=channel_map),
                          backend=backend, clock=clock)
    stream = backend.stream
    assert (stream.samplerate, stream.channels, stream.device) == (rate_hz, 6, "USB")
    frames = device_frames(plane_wave(square4, math.radians(35.0), rate_hz, 4.0), channel_map, 6)
    loc = locator(square4)
    loc.keep_frames = True
    targets = []
    for lo in range(0, frames.shape[0], 1000):
        stream.feed(frames[lo : lo + 1000])
        clock.t += 1000 / rate_hz
        block = capture.read(0)
        assert block is not None and block.shape[0] == 4
        targets += loc.push(block)
    assert abs(loc.samples_in - 4.0 * FS_HZ) <= 40  # the resampler's latency, at most
    speech = [f.azimuth_rad for f in loc.frames if f.speech]
    assert len(speech) > 10
    assert angle_error_deg(float(np.median(speech)), math.radians(35.0)) < 2.0
    assert angle_error_deg(targets[-1].azimuth_rad, math.radians(35.0)) < 3.0
    st = capture.status()
    assert (st.state, st.device, st.device_rate_hz, st.pipeline_rate_hz) == ("running", "USB Array",
                                                                               rate_hz, FS_HZ)
    assert st.channel_map == channel_map and st.overflows == st.dropped_blocks == 0
    assert st.resample_cpu_ms_per_s is not None and st.resample_cpu_ms_per_s > 0


def test_the_device_default_rate_is_used_unless_one_is_set() -> None:
    backend = FakeBackend(rate_hz=44100)
    LiveCapture(4, CaptureSettings(), backend=backend)
    assert backend.stream.samplerate == 44100 and backend.stream.channels == 4
    LiveCapture(4, CaptureSettings(device_rate_hz=48000), backend=backend)
    assert backend.stream.samplerate == 48000


def test_overflow_flags_and_blocks_the_consumer_missed_are_counted() -> None:
    backend = FakeBackend(channels=4)
    capture = LiveCapture(4, CaptureSettings(block_s=0.02, queue_s=0.1), backend=backend)
    block = np.zeros((960, 4))
    for k in range(12):
        backend.stream.feed(block, overflow=k in (2, 7, 9))
    st = capture.status()
    assert (st.blocks, st.overflows) == (12, 3)
    assert st.dropped_blocks == 12 - 5  # a queue of 0.1 s holds 5 blocks of 0.02 s
    assert sum(capture.read(0) is not None for _ in range(8)) == 5


def test_a_device_that_disappears_is_a_fault_and_capture_resumes_when_it_returns() -> None:
    backend = FakeBackend(channels=4)
    clock = Clock()
    capture = LiveCapture(4, CaptureSettings(retry_first_s=0.5, retry_max_s=4.0), backend=backend,
                          clock=clock)
    first = backend.stream
    first.feed(np.zeros((960, 4)))
    assert capture.read(0) is not None and capture.generation == 1
    first.vanish()
    assert capture.read(0) is None
    st = capture.status()
    assert st.state == "fault" and "USB Array" in (st.fault or "") and "stopped" in (st.fault or "")
    assert st.faults == 1 and first.closed and st.retry_in_s == pytest.approx(0.5)
    waits = []
    for _ in range(5):  # still gone: the attempts back off 0.5, 1, 2, 4, 4 s
        clock.t += capture.status().retry_in_s or 0.0
        assert capture.read(0) is None
        waits.append(capture.status().retry_in_s)
        assert "not found" in (capture.status().fault or "")
    assert waits == [1.0, 2.0, 4.0, 4.0, 4.0]
    backend.present = True
    clock.t += 4.0
    assert capture.read(0) is None  # reopens (PortAudio re-initialised to see it again)
    st = capture.status()
    assert (st.state, st.fault, st.reconnects, st.faults) == ("running", None, 1, 1)
    assert capture.generation == 2 and backend.stream is not first and backend.reinitialised >= 1
    backend.stream.feed(np.ones((960, 4)))
    block = capture.read(0)
    assert block is not None and block.shape == (4, 320 - 10)  # 10 samples of filter latency


def test_a_device_that_goes_silent_is_a_fault_after_the_stall_time() -> None:
    backend = FakeBackend(channels=4)
    clock = Clock()
    capture = LiveCapture(4, CaptureSettings(stall_s=1.0), backend=backend, clock=clock)
    clock.t += 0.9
    assert capture.read(0) is None and capture.status().state == "running"
    clock.t += 0.2
    assert capture.read(0) is None
    st = capture.status()
    assert st.state == "fault" and "no audio" in (st.fault or "") and "1.1 s" in (st.fault or "")


def test_a_missing_device_at_start_is_a_fault_not_an_error() -> None:
    backend = FakeBackend(present=False)
    clock = Clock()
    capture = LiveCapture(4, CaptureSettings(device="USB"), backend=backend, clock=clock)
    st = capture.status()
    assert st.state == "fault" and "'USB' not found" in (st.fault or "") and st.reconnects == 0
    backend.present = True
    clock.t += 1.0
    capture.read(0)
    assert capture.status().state == "running" and capture.generation == 1


def test_a_channel_map_the_device_cannot_give_is_a_fault_naming_the_channels() -> None:
    capture = LiveCapture(4, CaptureSettings(channel_map=(0, 1, 2, 7)), backend=FakeBackend(channels=6))
    fault = capture.status().fault or ""
    assert "6 input channel(s)" in fault and "channel 7" in fault


@pytest.mark.parametrize(
    ("settings", "words"),
    [(dict(channel_map=(0, 1, 2)), ["3 entries", "4 mics"]),
     (dict(channel_map=(0, 1, 1, 2)), ["channel twice"]),
     (dict(channel_map=(0, -1, 2, 3)), ["numbered from 0"]),
     (dict(device_rate_hz=1000), ["1000 Hz", "8000-384000"])],
    ids=["short-map", "duplicate", "negative", "rate"],
)
def test_bad_capture_settings_are_config_errors(settings: dict[str, object], words: list[str]) -> None:
    with pytest.raises(ConfigError) as err:
        LiveCapture(4, CaptureSettings(**settings), backend=FakeBackend())  # type: ignore[arg-type]
    for word in words:
        assert word in str(err.value)


def test_an_odd_device_rate_is_refused_with_the_rates_that_work() -> None:
    capture = LiveCapture(4, CaptureSettings(device_rate_hz=44101), backend=FakeBackend())
    st = capture.status()
    assert st.state == "fault" and "44101 Hz" in (st.fault or "") and "48000" in (st.fault or "")


def test_close_stops_the_stream_and_blocks_ends() -> None:
    backend = FakeBackend(channels=4)
    capture = LiveCapture(4, backend=backend)
    capture.close()
    assert backend.stream.closed and list(capture.blocks(0.01)) == []
    assert capture.status().state == "closed"


def test_the_device_list_shows_inputs_only() -> None:
    devices = list_input_devices(FakeBackend(name="Focusrite 18i20", channels=18, rate_hz=44100))
    assert len(devices) == 1
    d = devices[0]
    assert (d.index, d.name, d.host_api, d.max_input_channels, d.default_rate_hz, d.default) == (
        1, "Focusrite 18i20", "ALSA", 18, 44100.0, True)
    assert list_input_devices(FakeBackend(present=False)) == []


def test_without_portaudio_capture_and_the_device_list_are_driver_faults(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import tracker.audio.capture as capture_module

    def missing() -> None:
        raise DriverFault("live capture needs the PortAudio library (not found)")

    monkeypatch.setattr(capture_module, "sounddevice_backend", missing)
    with pytest.raises(DriverFault, match="PortAudio"):
        LiveCapture(4)
    with pytest.raises(DriverFault, match="PortAudio"):
        list_input_devices()
