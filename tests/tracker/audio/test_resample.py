"""The streaming resampler: resample_poly's output whatever the blocks, no trace of block edges."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import resample_poly

from tracker.audio.resample import StreamingResampler
from tracker.errors import ConfigError, DataError


@pytest.mark.parametrize(("fs_in", "fs_out"), [(48000, 16000), (44100, 16000), (32000, 16000),
                                               (8000, 16000), (96000, 16000), (16000, 16000)])
@pytest.mark.parametrize("blocks", [[1], [7, 1024, 333, 4096, 5], [441], [100000]],
                         ids=["one-sample", "mixed", "441", "whole"])
def test_blocks_give_resample_poly_of_the_whole_signal(fs_in: int, fs_out: int,
                                                       blocks: list[int]) -> None:
    x = np.random.default_rng(fs_in).standard_normal((3, 9001))
    r = StreamingResampler(fs_in, fs_out, 3)
    outs, i, k = [], 0, 0
    while i < x.shape[1]:
        n = blocks[k % len(blocks)]
        outs.append(r.process(x[:, i : i + n]))
        i, k = i + n, k + 1
    outs.append(r.flush())
    y = np.concatenate(outs, axis=1)
    expected = resample_poly(x, r.up, r.down, axis=1)
    assert y.shape == expected.shape
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("fs_in", [44100, 48000])
def test_a_tone_streamed_in_blocks_comes_out_clean(fs_in: int) -> None:
    """A 1 kHz tone in 0.02 s blocks: at 16 kHz it is the same tone within 0.2 % (the filter's
    pass-band ripple), at block edges as elsewhere (no clicks)."""
    t_in = np.arange(2 * fs_in) / fs_in
    x = np.sin(2 * np.pi * 1000.0 * t_in)[None, :]
    r = StreamingResampler(fs_in, 16000, 1)
    n = int(0.02 * fs_in)
    y = np.concatenate([r.process(x[:, i : i + n]) for i in range(0, x.shape[1], n)], axis=1)[0]
    t_out = np.arange(y.size) / 16000
    ideal = np.sin(2 * np.pi * 1000.0 * t_out)
    inner = slice(200, y.size - 200)  # the start's zero history aside
    assert np.max(np.abs(y[inner] - ideal[inner])) < 2e-3
    jumps = np.abs(np.diff(y[inner]))
    assert jumps.max() < 1.01 * np.abs(np.diff(ideal[inner])).max()


def test_odd_ratios_and_bad_blocks_are_refused() -> None:
    with pytest.raises(ConfigError, match="44101 Hz to 16000 Hz"):
        StreamingResampler(44101, 16000, 2)
    with pytest.raises(DataError, match=r"\(2, n\)"):
        StreamingResampler(48000, 16000, 2).process(np.zeros((3, 10)))
