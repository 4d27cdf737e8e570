"""Live capture from a sound card that survives real ones: any common rate, a channel map,
overflow counts, and a fault with recovery when the device goes away.

:class:`LiveCapture` opens a PortAudio input stream (through sounddevice, or any object with the
same ``InputStream``/``query_devices`` interface: tests drive a fake one) with a callback. The
callback (PortAudio's thread) only counts the device's overflow flags, picks the array's
microphones out of the device's channels (``channel_map[i]`` is the device channel of mic ``i``)
and queues the block; the consumer (:meth:`LiveCapture.blocks`, the audio stream's thread)
resamples it to the pipeline's rate (:class:`~tracker.audio.resample.StreamingResampler`, state
carried across blocks) and hands it on.

When the device disappears (the stream stops by itself, or no block arrives for ``stall_s``) the
capture closes it, reports the fault in :meth:`LiveCapture.status` and tries to open it again
after 0.5 s, then 1, 2, 4 ... up to ``retry_max_s``; when it returns, capture resumes (a new
``generation``: the consumer restarts its stream clock). A device named by a part of its name is
found again even when it comes back under another index.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tracker.audio.resample import StreamingResampler
from tracker.errors import ConfigError, DriverFault

FloatArray = NDArray[np.float64]
PIPELINE_RATE_HZ = 16000


def sounddevice_backend() -> Any:  # noqa: ANN401 - the sounddevice module
    """Import sounddevice on demand; a missing package or PortAudio library is a DriverFault."""
    try:
        import sounddevice
    except ImportError as exc:
        raise DriverFault(
            "live capture needs the 'sounddevice' package (pip install sounddevice)") from exc
    except OSError as exc:  # sounddevice raises OSError when libportaudio is missing
        raise DriverFault(f"live capture needs the PortAudio library ({exc}); "
                          "install it with: apt-get install libportaudio2") from exc
    return sounddevice


@dataclass(frozen=True, slots=True)
class CaptureSettings:
    """How to open the sound card.

    Attributes
    ----------
    device : int or str, optional
        PortAudio device index, or a part of its name; the default input device when None.
    device_rate_hz : int, optional
        The rate to open the device at; the device's default rate when None (resampled to
        ``pipeline_rate_hz``).
    channel_map : tuple of int, optional
        The device channel (from 0) of each array microphone, in the array file's order; the
        first ``n_mics`` channels when None.
    pipeline_rate_hz : int
    block_s : float
        The device's callback block (s).
    stall_s : float
        No block for this long: the device is gone.
    retry_first_s, retry_max_s : float
        Reopening waits ``retry_first_s``, doubling up to ``retry_max_s``.
    queue_s : float
        Audio the callback may queue ahead of the consumer; more is dropped (and counted).
    """

    device: int | str | None = None
    device_rate_hz: int | None = None
    channel_map: tuple[int, ...] | None = None
    pipeline_rate_hz: int = PIPELINE_RATE_HZ
    block_s: float = 0.02
    stall_s: float = 1.0
    retry_first_s: float = 0.5
    retry_max_s: float = 10.0
    queue_s: float = 5.0

    def __post_init__(self) -> None:
        if self.device_rate_hz is not None and not 8000 <= self.device_rate_hz <= 384000:
            raise ConfigError(f"audio device rate {self.device_rate_hz} Hz is outside 8000-384000 Hz")
        if self.channel_map is not None:
            bad = [c for c in self.channel_map if not 0 <= c < 256]
            if not self.channel_map or bad:
                raise ConfigError(f"audio channel map {list(self.channel_map)}: device channels "
                                  "are numbered from 0 (and below 256)")
            if len(set(self.channel_map)) != len(self.channel_map):
                raise ConfigError(f"audio channel map {list(self.channel_map)} names a device "
                                  "channel twice")
        for name in ("block_s", "stall_s", "retry_first_s", "retry_max_s", "queue_s"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"capture setting {name}={getattr(self, name)} must be > 0")

    def mics_to_channels(self, n_mics: int) -> tuple[int, ...]:
        """The device channel of each microphone; ConfigError when the map does not fit."""
        if self.channel_map is None:
            return tuple(range(n_mics))
        if len(self.channel_map) != n_mics:
            raise ConfigError(f"audio channel map {list(self.channel_map)} has "
                              f"{len(self.channel_map)} entries; the array has {n_mics} mics")
        return self.channel_map


@dataclass(frozen=True, slots=True)
class InputDevice:
    """An input device PortAudio offers."""

    index: int
    name: str
    host_api: str
    max_input_channels: int
    default_rate_hz: float
    default: bool


def list_input_devices(backend: Any = None) -> list[InputDevice]:  # noqa: ANN401
    """The devices with input channels (sounddevice's ``query_devices``); DriverFault when
    PortAudio is missing, an empty list when it has no input device."""
    sd = backend if backend is not None else sounddevice_backend()
    try:
        devices = list(sd.query_devices())
    except Exception as exc:  # PortAudioError: PortAudio failed to list
        raise DriverFault(f"cannot list audio devices: {exc}") from exc
    try:
        default_in = int(sd.default.device[0])
    except (AttributeError, TypeError, ValueError, IndexError):
        default_in = -1
    apis: dict[int, str] = {}
    with contextlib.suppress(Exception):
        apis = {i: str(api["name"]) for i, api in enumerate(sd.query_hostapis())}
    out = []
    for i, d in enumerate(devices):
        if int(d.get("max_input_channels", 0)) <= 0:
            continue
        index = int(d.get("index", i))
        out.append(InputDevice(index, str(d["name"]), apis.get(int(d.get("hostapi", -1)), ""),
                               int(d["max_input_channels"]), float(d["default_samplerate"]),
                               index == default_in))
    return out


@dataclass(frozen=True, slots=True)
class CaptureStatus:
    """What the status shows about live capture.

    ``state``: "running", "fault" (``fault`` says why; ``retry_in_s`` until the next attempt)
    or "closed". Counts since start: ``blocks`` from the device, ``overflows`` (blocks the
    device flagged: it lost input), ``dropped_blocks`` (blocks the consumer was too late for),
    ``faults``, ``reconnects`` (the device came back). ``resample_cpu_ms_per_s``: the callback's
    channel map and the resampler's CPU per second of audio.
    """

    state: str
    device: str
    device_rate_hz: int | None
    pipeline_rate_hz: int
    device_channels: int | None
    channel_map: tuple[int, ...]
    blocks: int
    overflows: int
    dropped_blocks: int
    faults: int
    reconnects: int
    fault: str | None
    retry_in_s: float | None
    resample_cpu_ms_per_s: float | None


class LiveCapture:
    """A sound card's input as pipeline-rate blocks (n_mics, n), surviving the device leaving.

    Parameters
    ----------
    n_mics : int
        The array's microphones (the blocks' channel count).
    settings : CaptureSettings
    backend : optional
        sounddevice, or an object with its ``query_devices`` and ``InputStream`` (tests).
    clock : optional
        Monotonic seconds (tests drive it).

    Raises DriverFault when PortAudio itself is missing, ConfigError when the settings do not
    fit the array. A device that is missing or refuses is not an error here: :meth:`status`
    shows the fault and the capture keeps trying.
    """

    def __init__(self, n_mics: int, settings: CaptureSettings | None = None, backend: Any = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.settings = settings if settings is not None else CaptureSettings()
        self.n_mics = int(n_mics)
        self.n_channels = self.n_mics
        self.fs_hz = self.settings.pipeline_rate_hz
        self._map = np.asarray(self.settings.mics_to_channels(self.n_mics), dtype=np.intp)
        self._backend = backend if backend is not None else sounddevice_backend()
        self._clock = clock
        self._queue: queue.Queue[FloatArray] = queue.Queue(
            maxsize=max(2, int(self.settings.queue_s / self.settings.block_s)))
        self._wake = threading.Event()
        self._stream: Any = None
        self._resampler: StreamingResampler | None = None
        self._device_name = str(self.settings.device) if self.settings.device is not None else "default"
        self._device_rate_hz: int | None = None
        self._device_channels: int | None = None
        self._ended = False  # the stream finished by itself (PortAudio's finished callback)
        self._last_block_t = 0.0
        self._retry_at: float | None = None
        self._backoff_s = self.settings.retry_first_s
        self._fault: str | None = None
        self._closed = False
        self.generation = 0  # +1 each time the device is opened (a new stream clock)
        self.blocks_in = self.overflows = self.dropped_blocks = self.faults = self.reconnects = 0
        self._cpu_s = 0.0  # the consumer's resampling
        self._callback_cpu_s = 0.0  # the callback's channel map and copy
        self._audio_s = 0.0
        self._open_or_fault()

    # -- the device --------------------------------------------------------------------------

    def _open(self) -> None:
        s, sd = self.settings, self._backend
        try:
            info = sd.query_devices(s.device, "input")
        except Exception as exc:  # ValueError / PortAudioError: no such device now
            raise DriverFault(f"audio input device {self._device_name!r} not found ({exc})") from exc
        self._device_name = str(info["name"])
        needed = int(self._map.max()) + 1
        available = int(info["max_input_channels"])
        if needed > available:
            raise DriverFault(f"audio input device {self._device_name!r} has {available} input "
                              f"channel(s); the channel map needs channel {needed - 1}")
        rate = int(s.device_rate_hz or round(float(info["default_samplerate"])))
        try:
            resampler = StreamingResampler(rate, s.pipeline_rate_hz, self.n_mics)
        except ConfigError as exc:
            raise DriverFault(f"audio input device {self._device_name!r}: {exc}") from exc
        self._ended = False
        try:
            stream = sd.InputStream(device=s.device, channels=needed, samplerate=rate,
                                    dtype="float32", blocksize=max(1, round(s.block_s * rate)),
                                    callback=self._callback, finished_callback=self._finished)
            stream.start()
        except Exception as exc:  # PortAudioError, ValueError: busy, gone, rate refused
            raise DriverFault(f"cannot open audio input device {self._device_name!r} with "
                              f"{needed} channels at {rate} Hz: {exc}") from exc
        self._stream, self._resampler = stream, resampler
        self._device_rate_hz, self._device_channels = rate, needed
        self._last_block_t = self._clock()
        self.generation += 1

    def _open_or_fault(self) -> None:
        was_fault = self._fault is not None
        if was_fault:
            self._refresh_devices()
        try:
            self._open()
        except DriverFault as exc:
            self._set_fault(str(exc))
            return
        self._fault, self._retry_at = None, None
        if was_fault:
            self.reconnects += 1

    def _set_fault(self, reason: str) -> None:
        """Close the stream, say why, and plan the next attempt (back-off doubling)."""
        self._close_stream()
        if self._fault is None:
            self.faults += 1
            self._backoff_s = self.settings.retry_first_s
        else:
            self._backoff_s = min(2.0 * self._backoff_s, self.settings.retry_max_s)
        self._fault = reason
        self._retry_at = self._clock() + self._backoff_s
        while True:  # what was queued belongs to the old stream clock
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break

    def _close_stream(self) -> None:
        stream, self._stream = self._stream, None
        if stream is not None:
            with contextlib.suppress(Exception):  # a vanished device may refuse to stop
                stream.stop()
            with contextlib.suppress(Exception):
                stream.close()

    def _refresh_devices(self) -> None:
        """PortAudio lists devices once per initialisation: re-initialise it before reopening
        (our stream is closed), or a device plugged back in is never seen again."""
        terminate = getattr(self._backend, "_terminate", None)
        initialize = getattr(self._backend, "_initialize", None)
        if callable(terminate) and callable(initialize):
            with contextlib.suppress(Exception):
                terminate()
                initialize()

    # -- PortAudio's thread ------------------------------------------------------------------

    def _callback(self, indata: Any, frames: int, time_info: Any, status: Any) -> None:  # noqa: ANN401
        """One device block: count its overflow flag, pick the mics, queue it (never blocks)."""
        t0 = time.thread_time()
        self._last_block_t = self._clock()
        self.blocks_in += 1
        if getattr(status, "input_overflow", False):
            self.overflows += 1
        try:
            self._queue.put_nowait(np.asarray(indata)[:, self._map].T.astype(float))
        except queue.Full:
            self.dropped_blocks += 1
        self._wake.set()
        self._callback_cpu_s += time.thread_time() - t0

    def _finished(self) -> None:
        self._ended = True
        self._wake.set()

    # -- the consumer ------------------------------------------------------------------------

    def read(self, timeout_s: float = 0.1) -> FloatArray | None:
        """The next block at the pipeline's rate, shape (n_mics, n), or None when none came
        within ``timeout_s`` (the device checked and, when gone, faulted or reopened)."""
        if self._closed:
            return None
        if self._fault is not None:
            assert self._retry_at is not None
            wait = self._retry_at - self._clock()
            if wait > 0:
                self._wake.wait(min(timeout_s, wait))
                self._wake.clear()
                return None
            self._open_or_fault()
            return None
        try:
            raw = self._queue.get(timeout=timeout_s) if timeout_s > 0 else self._queue.get_nowait()
        except queue.Empty:
            self._check_alive()
            return None
        return self._resample(raw)

    def _check_alive(self) -> None:
        stream = self._stream
        try:
            active = bool(stream.active) if stream is not None else False
        except Exception:  # PortAudioError on a dead stream
            active = False
        silent_s = self._clock() - self._last_block_t
        if self._ended or not active:
            self._set_fault(f"audio input device {self._device_name!r} stopped (unplugged or "
                            "taken by another program); retrying")
        elif silent_s > self.settings.stall_s:
            self._set_fault(f"no audio from device {self._device_name!r} for {silent_s:.1f} s "
                            "(unplugged?); retrying")

    def _resample(self, raw: FloatArray) -> FloatArray:
        assert self._resampler is not None
        t0 = time.thread_time()
        out = self._resampler.process(raw)
        self._cpu_s += time.thread_time() - t0
        self._audio_s += raw.shape[1] / float(self._device_rate_hz or self.fs_hz)
        return out

    def blocks(self, block_s: float = 0.1) -> Iterator[FloatArray]:
        """Pipeline-rate blocks until :meth:`close` (none while the device is away: watch
        :attr:`generation`, which changes when it comes back). ``block_s`` is how long to wait
        for one before checking the device."""
        while not self._closed:
            block = self.read(block_s)
            if block is not None and block.shape[1] > 0:
                yield block

    def close(self) -> None:
        """Stop capturing (thread-safe; wakes a waiting :meth:`blocks`)."""
        self._closed = True
        self._wake.set()
        self._close_stream()

    def status(self) -> CaptureStatus:
        retry = None
        if self._fault is not None and self._retry_at is not None:
            retry = max(0.0, self._retry_at - self._clock())
        state = "closed" if self._closed else ("fault" if self._fault is not None else "running")
        cpu_s = self._cpu_s + self._callback_cpu_s
        cpu = 1000.0 * cpu_s / self._audio_s if self._audio_s > 0 else None
        return CaptureStatus(state, self._device_name, self._device_rate_hz,
                             self.settings.pipeline_rate_hz, self._device_channels,
                             tuple(int(c) for c in self._map), self.blocks_in, self.overflows,
                             self.dropped_blocks, self.faults, self.reconnects, self._fault, retry,
                             cpu)
