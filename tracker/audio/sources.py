"""Audio sources behind one small Protocol: WAV files and simulated rooms (live capture:
:mod:`tracker.audio.capture`)."""

from __future__ import annotations

import struct
import wave
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from tracker.errors import DataError

if TYPE_CHECKING:  # a room simulation needs scipy.signal and pyroomacoustics: not for WAV files
    from tracker.audio.room import Recording

FloatArray = NDArray[np.float64]


class AudioSource(Protocol):
    """Multichannel audio delivered in blocks of shape (n_channels, n_samples)."""

    fs_hz: int
    n_channels: int

    def blocks(self, block_s: float) -> Iterator[FloatArray]:
        """Yield consecutive blocks of about ``block_s`` seconds until the source ends."""
        ...

    def close(self) -> None:
        """Release the device or file."""
        ...


_PCM, _IEEE_FLOAT, _EXTENSIBLE = 0x0001, 0x0003, 0xFFFE


def _wav_samples(raw: bytes) -> tuple[int, NDArray[np.generic]]:
    """The sample rate and the samples (n_samples, n_channels) of a RIFF/WAVE file's bytes,
    as ``scipy.io.wavfile.read`` gives them: PCM 8-bit unsigned, 16/32-bit signed, 24-bit as
    int32 with the sample in the upper three bytes, IEEE float 32/64 (also inside
    WAVE_FORMAT_EXTENSIBLE). Raises ValueError naming what is wrong."""
    if len(raw) < 12 or raw[:4] not in (b"RIFF", b"RIFX") or raw[8:12] != b"WAVE":
        raise ValueError("no RIFF/WAVE header")
    order = "<" if raw[:4] == b"RIFF" else ">"
    fmt: tuple[int, int, int, int, int] | None = None
    pos = 12
    while pos + 8 <= len(raw):
        chunk, size = raw[pos : pos + 4], struct.unpack(order + "I", raw[pos + 4 : pos + 8])[0]
        body = raw[pos + 8 : pos + 8 + size]
        if chunk == b"fmt ":
            if len(body) < 16:
                raise ValueError(f"fmt chunk of {len(body)} bytes")
            tag, n_channels, fs_hz, _, block_align, bits = struct.unpack(order + "HHIIHH", body[:16])
            if tag == _EXTENSIBLE and len(body) >= 26:
                tag = struct.unpack(order + "H", body[24:26])[0]  # the sub-format GUID's first bytes
            fmt = (tag, n_channels, fs_hz, block_align, bits)
        elif chunk == b"data":
            if fmt is None:
                raise ValueError("data chunk before the fmt chunk")
            return fmt[2], _decode(body, order, *fmt)
        pos += 8 + size + (size & 1)  # chunks are padded to an even size
    raise ValueError("no data chunk" if fmt is not None else "no fmt chunk")


def _decode(body: bytes, order: str, tag: int, n_channels: int, fs_hz: int, block_align: int,
            bits: int) -> NDArray[np.generic]:
    """The data chunk's samples, shape (n_samples, n_channels)."""
    width = (bits + 7) // 8
    if n_channels < 1 or block_align != n_channels * width:
        raise ValueError(f"{n_channels} channels of {bits} bits in blocks of {block_align} bytes")
    usable = len(body) - len(body) % block_align  # a truncated last frame is dropped
    if tag == _PCM and width in (1, 2, 4):
        dtype = np.dtype(order + {1: "u1", 2: "i2", 4: "i4"}[width])
        data = np.frombuffer(body, dtype=dtype, count=usable // width)
    elif tag == _PCM and width == 3:
        triples = np.frombuffer(body, dtype=np.uint8, count=usable).reshape(-1, 3)
        if order == ">":
            triples = triples[:, ::-1]
        words = np.zeros((triples.shape[0], 4), dtype=np.uint8)
        words[:, 1:] = triples  # little-endian int32 with the sample in the upper bytes
        data = words.view("<i4").ravel()
    elif tag == _IEEE_FLOAT and width in (4, 8):
        dtype = np.dtype(order + {4: "f4", 8: "f8"}[width])
        data = np.frombuffer(body, dtype=dtype, count=usable // width)
    else:
        raise ValueError(f"format tag {tag:#06x} with {bits}-bit samples is not supported")
    return data.reshape(-1, n_channels)


def read_wav(path: str | Path) -> tuple[int, FloatArray]:
    """Read a WAV file as float samples in [-1, 1].

    PCM 8/16/24/32-bit and float 32/64-bit files (plain or WAVE_FORMAT_EXTENSIBLE), read with
    the standard library and numpy (``scipy.io`` cost a third of a second to import); integer
    samples are divided by their type's largest value, as before.

    Returns
    -------
    fs_hz : int
    audio : ndarray, shape (n_channels, n_samples)

    Raises
    ------
    DataError
        The file is missing, not a WAV file, or empty.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError as exc:
        raise DataError(f"{path}: file not found") from exc
    except OSError as exc:
        raise DataError(f"{path}: not a readable WAV file ({exc})") from exc
    try:
        fs_hz, data = _wav_samples(raw)
    except (ValueError, struct.error) as exc:
        raise DataError(f"{path}: not a readable WAV file ({exc})") from exc
    if data.size == 0:
        raise DataError(f"{path}: WAV file holds no samples")
    if data.dtype == np.uint8:
        audio = (data.astype(float) - 128.0) / 128.0
    elif np.issubdtype(data.dtype, np.integer):
        audio = data.astype(float) / float(np.iinfo(data.dtype.name).max)
    else:
        audio = data.astype(float)
    return int(fs_hz), np.ascontiguousarray(audio.T)


def write_wav(path: str | Path, fs_hz: int, audio: FloatArray) -> None:
    """Write (n_channels, n_samples) float audio as 16-bit PCM, peak-normalised to 0.9 if it clips."""
    audio = np.asarray(audio)
    if audio.ndim == 1:
        audio = audio[None, :]
    peak = float(np.max(np.abs(audio))) if audio.size else 0.0
    scale = 0.9 / peak if peak > 0.9 else 1.0
    pcm = np.round(audio.T * scale * 32767).astype("<i2")
    with wave.open(str(Path(path)), "wb") as out:
        out.setnchannels(int(audio.shape[0]))
        out.setsampwidth(2)
        out.setframerate(int(fs_hz))
        out.writeframes(np.ascontiguousarray(pcm).tobytes())


class WavSource:
    """A multichannel WAV file read in blocks."""

    def __init__(self, path: str | Path) -> None:
        self.fs_hz, self._audio = read_wav(path)
        self.n_channels = int(self._audio.shape[0])

    def blocks(self, block_s: float) -> Iterator[FloatArray]:
        n = max(1, int(round(block_s * self.fs_hz)))
        for start in range(0, self._audio.shape[1], n):
            yield self._audio[:, start : start + n]

    def close(self) -> None:
        return None


class RoomSource:
    """A simulated room recording (see :mod:`tracker.audio.room`) played out in blocks."""

    def __init__(self, recording: Recording) -> None:
        self.recording = recording
        self.fs_hz = recording.fs_hz
        self.n_channels = int(recording.audio.shape[0])

    def blocks(self, block_s: float) -> Iterator[FloatArray]:
        n = max(1, int(round(block_s * self.fs_hz)))
        audio = self.recording.audio
        for start in range(0, audio.shape[1], n):
            yield audio[:, start : start + n]

    def close(self) -> None:
        return None
