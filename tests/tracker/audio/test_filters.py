"""The scipy-free filters give scipy's numbers (they replace scipy.signal and scipy.ndimage in the
speech detector and the map tracker, whose imports cost every 'tracker audio' command 1-2 s), and
need no numba either (its start-up cost the command 0.45 s)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy import ndimage, signal

from tracker.audio.filters import (
    butter_lowpass_sos,
    filter_history,
    gaussian_blur,
    running_mean,
    running_min,
    sosfilt,
    sosfilt_history,
)

RNG = np.random.default_rng(0)
X = RNG.standard_normal(20000)


@pytest.mark.parametrize("fs_hz", [8000, 16000, 44100, 48000])
def test_butterworth_sections_and_filtering_are_scipys(fs_hz):
    cutoff = min(1000.0, 0.45 * fs_hz)
    expected = signal.butter(4, cutoff, "lowpass", fs=fs_hz, output="sos")
    sos = butter_lowpass_sos(4, cutoff, fs_hz)
    np.testing.assert_array_equal(sos, expected)
    np.testing.assert_allclose(sosfilt(sos, X), signal.sosfilt(expected, X), rtol=0, atol=1e-12)


@pytest.mark.parametrize("block", [1, 160, 1600, 7919])
def test_filtering_in_blocks_gives_the_whole_signals_samples(block):
    sos = butter_lowpass_sos(4, 1000.0, 16000)
    history, parts = filter_history(sos), []
    for start in range(0, 12000, block):
        part, history = sosfilt_history(sos, X[start : min(start + block, 12000)], history)
        parts.append(part)
    np.testing.assert_allclose(np.concatenate(parts), signal.sosfilt(sos, X[:12000]),
                               rtol=0, atol=1e-12)


def test_sosfilt_refuses_unstable_sections():
    with pytest.raises(ValueError, match="unstable"):
        sosfilt(np.array([[1.0, 0.0, 0.0, 1.0, -2.0, 1.0]]), X[:10])


@pytest.mark.parametrize(("size", "origin"), [(5, 2), (5, 0), (188, 93), (16, 7), (16, -4), (3, 1)])
def test_running_mean_and_minimum_are_scipys(size, origin):
    np.testing.assert_allclose(running_mean(X, size, origin),
                               ndimage.uniform_filter1d(X, size, mode="nearest", origin=origin),
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(running_min(X, size, origin),
                                  ndimage.minimum_filter1d(X, size, mode="nearest", origin=origin))
    short = X[:3]  # shorter than the window: the edge values fill it
    np.testing.assert_array_equal(running_min(short, size, origin),
                                  ndimage.minimum_filter1d(short, size, mode="nearest", origin=origin))


@pytest.mark.parametrize("sigma", [0.3, 0.7, 1.2, 2.5])
def test_gaussian_blur_is_scipys(sigma):
    values = RNG.random((13, 181))
    np.testing.assert_array_equal(gaussian_blur(values, sigma),
                                  ndimage.gaussian_filter1d(values, sigma, axis=1, mode="nearest"))


def test_the_audio_chain_imports_neither_scipy_nor_numba():
    code = ("import sys, tracker.audio.pipeline, tracker.audio.stream, tracker.audio.head, "
            "tracker.audio.sources, tracker.cli.audio; "
            "print(','.join(sorted({m.split('.')[0] for m in sys.modules} & "
            "{'scipy', 'numba', 'llvmlite'})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_butterworth_order_and_cutoff_are_checked():
    with pytest.raises(ValueError, match="even order"):
        butter_lowpass_sos(3, 1000.0, 16000)
    with pytest.raises(ValueError, match="cutoff_hz"):
        butter_lowpass_sos(4, 9000.0, 16000)
