"""A stand-in for sounddevice that a test drives: devices that come and go, input streams whose
callback the test calls with the blocks a sound card would deliver."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from tracker.audio.array import MicArray, unit_vector
from tracker.audio.speech import synthetic_speech
from tracker.units import SPEED_OF_SOUND_M_PER_S


@dataclass
class Flags:
    """sounddevice.CallbackFlags: only what capture reads."""

    input_overflow: bool = False


class FakeStream:
    """sounddevice.InputStream's interface; :meth:`feed` plays the device's callback."""

    def __init__(self, backend: FakeBackend, device: Any = None, channels: int = 1,
                 samplerate: float = 48000, dtype: str = "float32", blocksize: int = 0,
                 callback: Callable[..., None] | None = None,
                 finished_callback: Callable[[], None] | None = None) -> None:
        if not backend.present:
            raise RuntimeError("Error opening InputStream: Device unavailable [PaErrorCode -9985]")
        self.backend, self.device, self.channels = backend, device, channels
        self.samplerate, self.dtype, self.blocksize = samplerate, dtype, blocksize
        self.callback, self.finished_callback = callback, finished_callback
        self.active = False
        self.closed = False
        backend.streams.append(self)

    def start(self) -> None:
        self.active = True

    def stop(self) -> None:
        self.active = False

    def close(self) -> None:
        self.active, self.closed = False, True

    def feed(self, frames: np.ndarray, overflow: bool = False) -> None:
        """One device block, shape (n_frames, channels), through the capture's callback."""
        assert frames.shape[1] == self.channels and self.callback is not None
        self.callback(frames.astype(np.float32), frames.shape[0], None, Flags(overflow))

    def vanish(self) -> None:
        """The device is unplugged: PortAudio ends the stream."""
        self.backend.present = False
        self.active = False
        if self.finished_callback is not None:
            self.finished_callback()


class FakeBackend:
    """sounddevice's module interface: ``query_devices``, ``InputStream``, ``default``."""

    def __init__(self, name: str = "USB Array", channels: int = 6, rate_hz: float = 48000.0,
                 present: bool = True) -> None:
        self.present = present
        self.input = {"name": name, "index": 1, "hostapi": 0, "max_input_channels": channels,
                      "max_output_channels": 0, "default_samplerate": rate_hz}
        self.output = {"name": "Speakers", "index": 0, "hostapi": 0, "max_input_channels": 0,
                       "max_output_channels": 2, "default_samplerate": 48000.0}
        self.streams: list[FakeStream] = []
        self.default = SimpleNamespace(device=(1, 0))
        self.reinitialised = 0

    def query_devices(self, device: Any = None, kind: str | None = None) -> Any:
        devices = [self.output] + ([self.input] if self.present else [])
        if device is None and kind is None:
            return devices
        if device is None:
            device = self.default.device[0]
        for d in devices:
            if device == d["index"] or (isinstance(device, str) and device in d["name"]):
                if kind == "input" and d["max_input_channels"] == 0:
                    raise ValueError(f"{d['name']!r} has no input channels")
                return d
        raise ValueError(f"No input device matching {device!r}")

    def query_hostapis(self) -> list[dict[str, Any]]:
        return [{"name": "ALSA"}]

    def InputStream(self, **kwargs: Any) -> FakeStream:  # noqa: N802 - sounddevice's name
        return FakeStream(self, **kwargs)

    def _terminate(self) -> None:
        pass

    def _initialize(self) -> None:
        self.reinitialised += 1

    @property
    def stream(self) -> FakeStream:
        return self.streams[-1]


def plane_wave(array: MicArray, azimuth_rad: float, fs_hz: int, duration_s: float,
               seed: int = 3, snr_db: float = 30.0) -> np.ndarray:
    """Speech from ``azimuth_rad`` as the array's mics hear it at ``fs_hz`` (exact fractional
    delays) plus white noise: shape (n_mics, n)."""
    speech = synthetic_speech(duration_s, fs_hz, seed=seed).samples
    n = speech.size
    spectrum = np.fft.rfft(speech, 2 * n)
    freqs = np.fft.rfftfreq(2 * n, 1.0 / fs_hz)
    arrival_s = -(array.positions_m @ unit_vector(azimuth_rad, 0.0)) / SPEED_OF_SOUND_M_PER_S
    audio = np.fft.irfft(spectrum[None, :] * np.exp(-2j * math.pi * freqs[None, :]
                                                    * arrival_s[:, None]), 2 * n)[:, :n]
    noise_std = math.sqrt(float(np.mean(speech**2)) / 10 ** (snr_db / 10))
    return audio + noise_std * np.random.default_rng(seed + 1).standard_normal(audio.shape)


def device_frames(mics: np.ndarray, channel_map: tuple[int, ...], channels: int,
                  seed: int = 5) -> np.ndarray:
    """The device's interleaved view, shape (n, channels): mic i on ``channel_map[i]``, the
    other channels faint noise (a card with more inputs than the array)."""
    out = 1e-4 * np.random.default_rng(seed).standard_normal((mics.shape[1], channels))
    for mic, channel in enumerate(channel_map):
        out[:, channel] = mics[mic]
    return out
