"""Audio sources behind one small Protocol: WAV files, simulated rooms and live capture."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.io import wavfile

from tracker.errors import DataError, DriverFault

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


def _sounddevice() -> Any:
    """Import sounddevice on demand; PortAudio problems become a DriverFault."""
    try:
        import sounddevice
    except ImportError as exc:
        raise DriverFault(
            "live capture needs the 'sounddevice' package (pip install sounddevice)"
        ) from exc
    except OSError as exc:  # sounddevice raises OSError when libportaudio is missing
        raise DriverFault(
            f"live capture needs the PortAudio library ({exc}); "
            "install it with: apt-get install libportaudio2"
        ) from exc
    return sounddevice


class LiveSource:
    """Live capture from a sound card through sounddevice (imported only when used).

    Parameters
    ----------
    n_channels : int
        Channels to record; must match the array's microphone count.
    fs_hz : int
    device : int or str, optional
        sounddevice device index or name; the default input device when omitted.
    """

    def __init__(self, n_channels: int, fs_hz: int = 16000, device: int | str | None = None
                 ) -> None:
        sd = _sounddevice()
        self.fs_hz = int(fs_hz)
        self.n_channels = int(n_channels)
        self.overflows = 0  # blocks read after PortAudio lost input (the reader fell behind)
        try:
            sd.check_input_settings(device=device, channels=n_channels, samplerate=fs_hz)
            self._stream = sd.InputStream(device=device, channels=n_channels, samplerate=fs_hz,
                                          dtype="float32")
            self._stream.start()
        except Exception as exc:  # PortAudioError or ValueError from a bad device/setting
            raise DriverFault(
                f"cannot open audio input device {device!r} with {n_channels} channels at "
                f"{fs_hz} Hz: {exc}"
            ) from exc

    def blocks(self, block_s: float) -> Iterator[FloatArray]:
        n = max(1, int(round(block_s * self.fs_hz)))
        while True:
            try:
                data, overflowed = self._stream.read(n)
            except Exception as exc:
                raise DriverFault(f"audio capture failed: {exc}") from exc
            if overflowed:
                self.overflows += 1
            yield np.asarray(data, dtype=float).T

    def close(self) -> None:
        self._stream.stop()
        self._stream.close()
