"""Streaming polyphase resampling: a sound card's rate to the pipeline's, block by block.

:class:`StreamingResampler` computes exactly what ``scipy.signal.resample_poly(x, up, down)``
computes on the whole recording (the same Kaiser-windowed FIR, ``half_len = 10 * max(up, down)``
taps each side, the same output instants ``n * down / up``), but as blocks arrive: it keeps the
last input samples the filter still needs, so block edges leave no trace (no clicks, no
restarted filter), whatever the block sizes. An output sample is given once the input reaches
its filter's last tap: the latency is ``half_len / up`` input samples (0.6 ms at 48 kHz -> 16 kHz,
2 ms at 44.1 kHz -> 16 kHz). :meth:`StreamingResampler.flush` gives the tail, as if zeros followed.

Each block is filtered by ``scipy.signal.upfirdn`` (compiled polyphase) over the kept history
and the new samples: about ``(2 * half_len + 1) / up`` multiply-adds per output sample and
channel (61 for 48 -> 16 kHz, 56 for 44.1 -> 16 kHz); ``bench/bench_capture.py`` prints the
cost per room.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from numpy.typing import NDArray

from tracker.errors import ConfigError, DataError

FloatArray = NDArray[np.float64]
MAX_RATIO_TERM = 1000  # up or down beyond this: a filter of 20 000+ taps; refuse the rate instead


def resample_filter(up: int, down: int) -> FloatArray:
    """``resample_poly``'s default filter for ``up/down``: shape (2 * half_len + 1,), gain ``up``."""
    from scipy.signal import firwin

    max_rate = max(up, down)
    half_len = 10 * max_rate
    return np.asarray(firwin(2 * half_len + 1, 1.0 / max_rate, window=("kaiser", 5.0)) * up)


class StreamingResampler:
    """Resample (n_channels, n) blocks from ``fs_in_hz`` to ``fs_out_hz`` with carried state.

    Parameters
    ----------
    fs_in_hz, fs_out_hz : int
        The rates; their ratio reduced to ``up/down`` must have both terms at most 1000.
    n_channels : int
    """

    def __init__(self, fs_in_hz: int, fs_out_hz: int, n_channels: int) -> None:
        if fs_in_hz <= 0 or fs_out_hz <= 0 or n_channels <= 0:
            raise ConfigError(f"resampler needs positive rates and channels (got {fs_in_hz} Hz -> "
                              f"{fs_out_hz} Hz, {n_channels} channels)")
        ratio = Fraction(int(fs_out_hz), int(fs_in_hz))
        self.up, self.down = ratio.numerator, ratio.denominator
        if max(self.up, self.down) > MAX_RATIO_TERM:
            raise ConfigError(f"cannot resample {fs_in_hz} Hz to {fs_out_hz} Hz: the ratio "
                              f"{self.up}/{self.down} needs too long a filter; use a standard "
                              "rate (16000, 32000, 44100, 48000, 96000 Hz)")
        self.fs_in_hz, self.fs_out_hz, self.n_channels = int(fs_in_hz), int(fs_out_hz), n_channels
        self.passthrough = self.up == self.down == 1
        self.half_len = 10 * max(self.up, self.down)
        self._h = resample_filter(self.up, self.down) if not self.passthrough else np.ones(1)
        self.n_taps = math.ceil(self._h.size / self.up)  # input samples under the filter
        # The kept input starts at an absolute index s with s * up = half_len (mod down): then
        # the next output's filter position, counted from the buffer's start, is a whole number
        # of output steps, and upfirdn's outputs land on it with no shift of the filter.
        self._align = (self.half_len * pow(self.up, -1, self.down)) % self.down if self.down > 1 else 0
        start = self._aligned(-(self.n_taps - 1))  # zeros before the first sample, as resample_poly
        self._buf = np.zeros((n_channels, -start))
        self._buf_start = start  # absolute input index of self._buf[:, 0]
        self._n_in = 0  # input samples received
        self._n_out = 0  # output samples given

    def _aligned(self, index: int) -> int:
        """The largest aligned input index <= ``index``."""
        return index - ((index - self._align) % self.down)

    @property
    def samples_in(self) -> int:
        return self._n_in

    @property
    def samples_out(self) -> int:
        return self._n_out

    def process(self, block: FloatArray) -> FloatArray:
        """Take a block, shape (n_channels, n); return the outputs it completed,
        shape (n_channels, m)."""
        block = np.asarray(block, dtype=float)
        if block.ndim != 2 or block.shape[0] != self.n_channels:
            raise DataError(f"resampler block has shape {block.shape}; expected "
                            f"({self.n_channels}, n)")
        if self.passthrough:
            self._n_in += block.shape[1]
            self._n_out += block.shape[1]
            return block
        self._buf = np.concatenate([self._buf, block], axis=1)
        self._n_in += block.shape[1]
        return self._emit(self._n_in)

    def flush(self) -> FloatArray:
        """The outputs left at the end (zeros assumed after the last input): after it the
        outputs number ``ceil(n_in * up / down)``, as ``resample_poly``'s."""
        if self.passthrough:
            return np.zeros((self.n_channels, 0))
        total = math.ceil(self._n_in * self.up / self.down)
        pad = max(0, (total * self.down + self.half_len) // self.up + 1 - self._n_in)
        self._buf = np.concatenate([self._buf, np.zeros((self.n_channels, pad))], axis=1)
        out = self._emit(self._n_in + pad, limit=total)
        return out

    def _emit(self, available: int, limit: int | None = None) -> FloatArray:
        """Outputs whose newest tap is below input index ``available``."""
        from scipy.signal import upfirdn

        # Output n's newest tap: input index (n * down + half_len) // up.
        n_ready = (available * self.up - self.half_len - 1) // self.down + 1
        if limit is not None:
            n_ready = min(n_ready, limit)
        n_new = max(0, n_ready - self._n_out)
        if n_new == 0:
            return np.zeros((self.n_channels, 0))
        # In upsampled samples from the buffer's start, output n sits at
        # n * down + half_len - buf_start * up: a multiple of down (the alignment).
        first = (self._n_out * self.down + self.half_len - self._buf_start * self.up) // self.down
        used = self._buf[:, : available - self._buf_start]
        y = upfirdn(self._h, used, self.up, self.down, axis=1)[:, first : first + n_new]
        self._n_out += n_new
        # Keep what the next output needs, from its oldest tap on (aligned).
        next_newest = (self._n_out * self.down + self.half_len) // self.up
        keep_from = self._aligned(next_newest - (self.n_taps - 1))
        if keep_from > self._buf_start:
            self._buf = self._buf[:, keep_from - self._buf_start :]
            self._buf_start = keep_from
        return np.asarray(y)
