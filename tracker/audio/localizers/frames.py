"""STFT frames shared by overlapping analysis windows: each frame is computed once, by start sample.

A window of ``n`` samples starting at sample ``s`` is analysed as the Hann-windowed frames
starting at ``s, s + h, s + 2h, ...`` (``h = nfft / 2``, :func:`window_frame_starts`), as
:func:`~tracker.audio.localizers.spectra.stft` does. Windows every 0.1 s (1600 samples at
16 kHz) on a 256-sample frame hop share their frames four windows apart, and a 1.5 s window
shares all of its frames with earlier windows: :class:`StftFrames` keeps each frame's power
and pair cross-spectra by its start sample, so every window sums them instead of transforming
its samples again (:mod:`.srp_kernels`). The spectra are the numbers the per-window STFT
gives (row by row the FFT is the same).
"""

from __future__ import annotations

import bisect

import numpy as np
from numpy.typing import NDArray

from tracker.audio.localizers.srp_kernels import PRODUCT_DTYPE, Float32Array, store_pair_products
from tracker.errors import DataError

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.int64]


def window_frame_starts(start: int, n_samples: int, nfft: int) -> IntArray:
    """Start samples of the STFT frames of the window ``[start, start + n_samples)``.

    Returns shape (n_frames,), ``n_frames = 1 + (n_samples - nfft) // (nfft // 2)``.
    """
    hop = nfft // 2
    n_frames = 1 + max(0, (n_samples - nfft) // hop)
    return np.asarray(start + hop * np.arange(n_frames, dtype=np.int64), dtype=np.int64)


class StftFrames:
    """Hann-windowed STFT frames of a multichannel signal, kept by their start sample.

    Each frame is stored in a row (rows are reused once a frame is forgotten) as

    * ``power[row]``, shape (nfft // 2 + 1,): the power averaged over the mics, every bin;
    * ``cross_re[:, row]``, ``cross_im[:, row]``, shape (n_pairs, n_band): the real and imaginary
      parts of the pair products ``X_i X_j*`` at the band's bins (of ``X / |X|`` with
      ``unit_magnitude``: per-frame PHAT);
    * ``rising[row]``, shape (n_band,): how much the power rose since the frame one hop
      earlier, ``clip(1 - P_prev / (P + 1e-30), 0, 1)`` at the band's bins (the onset weight
      before its exponent, :func:`~tracker.audio.localizers.spectra.onset_weights`), NaN while
      that frame is not kept (a window's first frame has no earlier frame of its own anyway).

    Parameters
    ----------
    n_mics, nfft : int
    band_bins : ndarray of int, shape (n_band,)
        The rfft bins the localizer steers (its band: consecutive bins).
    first, second : ndarray of int, shape (n_pairs,)
        The mics of each pair.
    unit_magnitude : bool
    """

    def __init__(self, n_mics: int, nfft: int, band_bins: IntArray, first: IntArray,
                 second: IntArray, unit_magnitude: bool = False) -> None:
        self.n_mics = int(n_mics)
        self.nfft = int(nfft)
        self.band_bins = np.asarray(band_bins, dtype=np.int64)
        self.first = np.asarray(first, dtype=np.int64)
        self.second = np.asarray(second, dtype=np.int64)
        self.unit_magnitude = unit_magnitude
        self._window = np.hanning(self.nfft + 1)[: self.nfft]
        self._row_of: dict[int, int] = {}
        self._order: list[int] = []  # the kept starts, increasing
        self._free: list[int] = []
        n_freq, n_band, n_pairs = self.nfft // 2 + 1, self.band_bins.size, self.first.size
        self.power: FloatArray = np.zeros((0, n_freq))
        self.rising: FloatArray = np.zeros((0, n_band))
        # Pair-major (n_pairs, n_rows, n_band): new frames are written, and windows' frames
        # gathered, a pair's contiguous band at a time.
        self.cross_re: Float32Array = np.zeros((n_pairs, 0, n_band), dtype=PRODUCT_DTYPE)
        self.cross_im: Float32Array = np.zeros((n_pairs, 0, n_band), dtype=PRODUCT_DTYPE)

    def _allocate(self, capacity: int) -> None:
        """Grow the row arrays to ``capacity`` rows (the new rows are free)."""
        used = self.power.shape[0]

        def grown(old: FloatArray, fill: float = 0.0) -> FloatArray:
            new = np.full((capacity, *old.shape[1:]), fill)
            new[:used] = old
            return new

        self.power = grown(self.power)
        self.rising = grown(self.rising, np.nan)
        def grown_pairs(old: Float32Array) -> Float32Array:
            new = np.zeros((old.shape[0], capacity, old.shape[2]), dtype=PRODUCT_DTYPE)
            new[:, :used] = old
            return new

        self.cross_re, self.cross_im = grown_pairs(self.cross_re), grown_pairs(self.cross_im)
        self._free += list(range(capacity - 1, used - 1, -1))

    def __len__(self) -> int:
        return len(self._row_of)

    def __contains__(self, start: object) -> bool:
        return start in self._row_of

    def add(self, audio: FloatArray, offset: int, starts: IntArray) -> None:
        """Compute the frames starting at ``starts`` (absolute samples, any shape) not kept yet.

        ``audio`` has shape (n_mics, n_samples); its column 0 is absolute sample ``offset``.
        """
        wanted = np.unique(np.asarray(starts, dtype=np.int64))
        new = np.array([s for s in wanted.tolist() if s not in self._row_of], dtype=np.int64)
        if new.size == 0:
            return
        local = new - offset
        if local[0] < 0 or local[-1] + self.nfft > audio.shape[1]:
            raise DataError(f"STFT frames at samples {int(new[0])}..{int(new[-1])} are outside the "
                            f"audio held ({offset}..{offset + audio.shape[1]})")
        segments = np.lib.stride_tricks.sliding_window_view(audio, self.nfft, axis=1)[:, local]
        spectra = np.fft.rfft(segments * self._window, axis=-1)  # (n_mics, n_new, n_freq)
        if len(self._free) < new.size:
            self._allocate(max(2 * self.power.shape[0], len(self) + new.size, 16))
        rows = np.array([self._free.pop() for _ in range(new.size)], dtype=np.int64)
        self.power[rows] = np.mean(np.abs(spectra) ** 2, axis=0)
        new_starts = new.tolist()
        self._row_of.update(zip(new_starts, rows.tolist(), strict=True))
        if self._order and new_starts[0] < self._order[-1]:
            for start in new_starts:
                bisect.insort(self._order, start)
        else:  # the usual case: later than every kept frame
            self._order.extend(new_starts)
        self._update_rising(new, rows)
        store_pair_products(spectra, int(self.band_bins[0]), rows, self.first, self.second,
                            self.unit_magnitude, self.cross_re, self.cross_im)

    def _update_rising(self, new: IntArray, rows: IntArray) -> None:
        """``rising`` of the new frames and of the kept frames one hop after them."""
        hop = self.nfft // 2
        after = [(self._row_of[s + hop], row) for s, row in zip(new.tolist(), rows.tolist(),
                                                                strict=True)
                 if s + hop in self._row_of]
        before = [(row, self._row_of[s - hop]) for s, row in zip(new.tolist(), rows.tolist(),
                                                                 strict=True)
                  if s - hop in self._row_of]
        pairs = np.array(after + before, dtype=np.int64).reshape(-1, 2)  # (row, previous row)
        if pairs.size:
            band = slice(int(self.band_bins[0]), int(self.band_bins[-1]) + 1)
            current = self.power[pairs[:, 0], band]
            previous = self.power[pairs[:, 1], band]
            self.rising[pairs[:, 0]] = np.clip(1.0 - previous / (current + 1e-30), 0.0, 1.0)

    def rows(self, starts: IntArray) -> IntArray:
        """Row of each frame start (same shape); every start must have been added."""
        starts = np.asarray(starts, dtype=np.int64)
        try:
            rows = [self._row_of[s] for s in starts.ravel().tolist()]
        except KeyError as exc:
            raise DataError(f"STFT frame at sample {exc.args[0]} asked for before it was added"
                            ) from None
        return np.asarray(rows, dtype=np.int64).reshape(starts.shape)

    def forget_before(self, sample: int) -> None:
        """Drop the frames starting before ``sample`` (no window needs them any more)."""
        drop = bisect.bisect_left(self._order, sample)
        if drop:
            rows = [self._row_of.pop(start) for start in self._order[:drop]]
            self.rising[rows] = np.nan
            self._free.extend(rows)
            del self._order[:drop]
