"""CPU of live capture per room: the callback (channel map, copy, queue) and the resampler to
16 kHz, for sound cards at 16, 44.1 and 48 kHz and arrays of 4 and 8 mics, in ms of CPU per
second of audio and % of one core; and the whole live path (capture + the console's streaming
localizer and map tracker) on speech from one talker.

The device is a stand-in with sounddevice's interface (no sound card on a server): the bench
calls the capture's callback with 20 ms blocks of a card with 2 more channels than the array, as
PortAudio would, and reads them back as the consumer thread does.

Run: .venv/bin/python bench/bench_capture.py [--seconds 20] [--repeat 3]
"""

from __future__ import annotations

import argparse
import math
import time
from types import SimpleNamespace
from typing import Any

import numpy as np

from tracker.audio.capture import CaptureSettings, LiveCapture


class _Stream:
    def __init__(self, **kw: Any) -> None:
        self.callback = kw["callback"]
        self.channels = kw["channels"]
        self.active = True

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def close(self) -> None: ...


class _Card:
    """A sound card with ``channels`` inputs at ``rate_hz`` (sounddevice's interface)."""

    def __init__(self, channels: int, rate_hz: int) -> None:
        self.info = {"name": "bench card", "max_input_channels": channels,
                     "default_samplerate": float(rate_hz)}
        self.default = SimpleNamespace(device=(0, 0))
        self.stream: _Stream | None = None

    def query_devices(self, device: Any = None, kind: Any = None) -> dict[str, Any]:
        return self.info

    def InputStream(self, **kw: Any) -> _Stream:  # noqa: N802 - sounddevice's name
        self.stream = _Stream(**kw)
        return self.stream


def capture_cost(n_mics: int, rate_hz: int, seconds: float, repeat: int) -> float:
    """Best CPU ms per s of audio of callback + resampling."""
    block = int(0.02 * rate_hz)
    frames = (0.1 * np.random.default_rng(0).standard_normal((block, n_mics + 2))).astype(np.float32)
    flags = SimpleNamespace(input_overflow=False)
    best = math.inf
    for _ in range(repeat):
        card = _Card(n_mics + 2, rate_hz)
        capture = LiveCapture(n_mics, CaptureSettings(channel_map=tuple(range(2, n_mics + 2))),
                              backend=card)
        assert card.stream is not None
        t0 = time.thread_time()
        for _ in range(int(seconds / 0.02)):
            card.stream.callback(frames, block, None, flags)
            capture.read(0)
        best = min(best, 1000.0 * (time.thread_time() - t0) / seconds)
    return best


def live_path_cost(rate_hz: int, seconds: float) -> tuple[float, float]:
    """CPU ms per s of audio of capture alone and capture + the console's streaming localizer
    (meeting pipeline, map tracker) on a talker at 30° heard by the 4-mic square."""
    from app.audio import load_meeting_array, meeting_pipeline
    from tests.tracker.audio.fake_sounddevice import device_frames, plane_wave
    from tracker.audio.stream import StreamingLocator

    array = load_meeting_array()
    frames = device_frames(plane_wave(array, math.radians(30.0), rate_hz, seconds), (2, 3, 4, 5), 6)
    card = _Card(6, rate_hz)
    capture = LiveCapture(4, CaptureSettings(channel_map=(2, 3, 4, 5)), backend=card)
    loc = StreamingLocator(meeting_pipeline(16000, array))
    assert card.stream is not None
    block = int(0.02 * rate_hz)
    flags = SimpleNamespace(input_overflow=False)
    pending: list[np.ndarray] = []
    t_capture = 0.0
    t0 = time.thread_time()
    for lo in range(0, frames.shape[0] - block + 1, block):
        t1 = time.thread_time()
        card.stream.callback(frames[lo : lo + block].astype(np.float32), block, None, flags)
        out = capture.read(0)
        t_capture += time.thread_time() - t1
        if out is not None:
            pending.append(out)
        if len(pending) == 5:  # the console pushes 0.1 s at a time
            loc.push(np.concatenate(pending, axis=1))
            pending = []
    total = time.thread_time() - t0
    latest = loc.latest
    assert latest is not None and abs(math.degrees(latest.azimuth_rad) - 30.0) < 3.0, latest
    return 1000.0 * t_capture / seconds, 1000.0 * total / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print("capture per room (callback + channel map + resampling to 16 kHz), 20 ms device blocks")
    print(f"{'mics':>4} {'card':>9} {'CPU ms/s':>9} {'% core':>7}")
    for n_mics in (4, 8):
        for rate in (16000, 44100, 48000):
            ms = capture_cost(n_mics, rate, args.seconds, args.repeat)
            print(f"{n_mics:>4} {rate / 1000:>6.1f} kHz {ms:>9.2f} {ms / 10:>7.2f}")
    print("\nthe live path per room: 4-mic square, one talker at 30°, meeting pipeline (map tracker)")
    print(f"{'card':>9} {'capture ms/s':>13} {'capture+localizer ms/s':>23} {'% core':>7}")
    live_path_cost(48000, 2.0)  # warm-up: compiled kernels loaded, caches filled
    for rate in (48000, 44100):
        cap, total = live_path_cost(rate, args.seconds)
        print(f"{rate / 1000:>5.1f} kHz {cap:>13.2f} {total:>23.2f} {total / 10:>7.2f}")


if __name__ == "__main__":
    main()
