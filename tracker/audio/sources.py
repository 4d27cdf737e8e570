"""Audio sources behind one small Protocol: WAV files and simulated rooms (live capture:
:mod:`tracker.audio.capture`)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.io import wavfile

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


def read_wav(path: str | Path) -> tuple[int, FloatArray]:
    """Read a WAV file as float samples in [-1, 1].

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
        fs_hz, data = wavfile.read(path)
    except FileNotFoundError as exc:
        raise DataError(f"{path}: file not found") from exc
    except (OSError, ValueError, EOFError) as exc:
        raise DataError(f"{path}: not a readable WAV file ({exc})") from exc
    data = np.asarray(data)
    if data.size == 0:
        raise DataError(f"{path}: WAV file holds no samples")
    if data.dtype == np.uint8:
        audio = (data.astype(float) - 128.0) / 128.0
    elif np.issubdtype(data.dtype, np.integer):
        audio = data.astype(float) / float(np.iinfo(data.dtype).max)
    else:
        audio = data.astype(float)
    audio = audio[:, None] if audio.ndim == 1 else audio
    return int(fs_hz), np.ascontiguousarray(audio.T)


def write_wav(path: str | Path, fs_hz: int, audio: FloatArray) -> None:
    """Write (n_channels, n_samples) float audio as 16-bit PCM, peak-normalised to 0.9 if it clips."""
    peak = float(np.max(np.abs(audio))) if audio.size else 0.0
    scale = 0.9 / peak if peak > 0.9 else 1.0
    pcm = np.round(np.asarray(audio).T * scale * 32767).astype(np.int16)
    wavfile.write(Path(path), int(fs_hz), pcm)


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
