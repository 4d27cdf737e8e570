"""Shared fixtures: arrays from examples/, free-field and simulated-room recordings with ground truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tracker.audio.array import MicArray, load_array, unit_vector
from tracker.audio.speech import synthetic_speech
from tracker.units import SPEED_OF_SOUND_M_PER_S

ARRAYS_DIR = Path(__file__).resolve().parents[3] / "examples" / "arrays"
FS_HZ = 16000


def example_array(name: str) -> MicArray:
    return load_array(ARRAYS_DIR / f"{name}.json")


def free_field(array: MicArray, azimuth_rad: float, elevation_rad: float = 0.0,
               duration_s: float = 1.0, snr_db: float = 30.0, seed: int = 0) -> np.ndarray:
    """Speech arriving as a plane wave (exact fractional delays) plus white noise; (n_mics, n)."""
    speech = synthetic_speech(duration_s, FS_HZ, seed=seed).samples
    n = speech.size
    spectrum = np.fft.rfft(speech, 2 * n)
    freqs = np.fft.rfftfreq(2 * n, 1.0 / FS_HZ)
    arrival_s = -(array.positions_m @ unit_vector(azimuth_rad, elevation_rad)) / SPEED_OF_SOUND_M_PER_S
    audio = np.fft.irfft(spectrum[None, :] * np.exp(-2j * np.pi * freqs[None, :] * arrival_s[:, None]),
                         2 * n)[:, :n]
    rng = np.random.default_rng(seed + 1000)
    noise_std = np.sqrt(np.mean(speech**2) / 10 ** (snr_db / 10))
    return audio + noise_std * rng.standard_normal(audio.shape)


def angle_error_deg(a_rad: float, b_rad: float) -> float:
    return float(abs(np.rad2deg(np.angle(np.exp(1j * (a_rad - b_rad))))))


@pytest.fixture(scope="session")
def square4() -> MicArray:
    return example_array("square4_65mm")
