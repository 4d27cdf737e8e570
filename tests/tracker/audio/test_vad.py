"""Speech activity: speech passes; fans, door slams, typing and coughs do not."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from tracker.audio.speech import synthetic_speech
from tracker.audio.vad import SpeechDetector, VadSettings
from tracker.errors import ConfigError

FS_HZ = 16000
DURATION_S = 4.0


def _room_noise(rng: np.random.Generator, level: float = 0.003) -> np.ndarray:
    return level * rng.standard_normal(int(DURATION_S * FS_HZ))


def fan(rng: np.random.Generator) -> np.ndarray:
    """Steady airflow plus blade-pass whine (180 Hz and harmonics into the speech band):
    loud, periodic and switched on during the recording, so the noise floor has not learnt it."""
    t = np.arange(int(DURATION_S * FS_HZ)) / FS_HZ
    air = signal.lfilter([1.0], [1.0, -0.95], rng.standard_normal(t.size))
    hum = sum(np.sin(2 * np.pi * 180.0 * k * t) / k**0.5 for k in range(1, 9))
    x = 0.02 * air / air.std() + 0.05 * hum
    x[: FS_HZ // 2] *= np.linspace(0.0, 1.0, FS_HZ // 2)  # it was switched on
    return x


def door_slam(rng: np.random.Generator) -> np.ndarray:
    """A bang: broadband impulse and a decaying 70 Hz panel thud, then silence."""
    x = _room_noise(rng)
    n = int(0.4 * FS_HZ)
    t = np.arange(n) / FS_HZ
    bang = (rng.standard_normal(n) * np.exp(-t / 0.02) + 3 * np.sin(2 * np.pi * 70 * t)
            * np.exp(-t / 0.08))
    start = FS_HZ
    x[start : start + n] += 0.3 * bang
    return x


def typing(rng: np.random.Generator) -> np.ndarray:
    """Key clicks (3 ms bursts) at 6-10 per second."""
    x = _room_noise(rng)
    position = int(0.2 * FS_HZ)
    while position < x.size - 100:
        click = rng.standard_normal(48) * np.exp(-np.arange(48) / 10.0)
        x[position : position + 48] += 0.2 * click
        position += int(rng.uniform(0.1, 0.17) * FS_HZ)
    return x


def cough(rng: np.random.Generator) -> np.ndarray:
    """Two coughs: 250 ms bursts of band-limited noise with a sharp attack."""
    x = _room_noise(rng)
    sos = signal.butter(4, [300.0, 3500.0], "bandpass", fs=FS_HZ, output="sos")
    for start_s in (1.0, 1.5):
        n = int(0.25 * FS_HZ)
        t = np.arange(n) / FS_HZ
        burst = signal.sosfilt(sos, rng.standard_normal(n)) * (1 - np.exp(-t / 0.005)) * np.exp(-t / 0.08)
        start = int(start_s * FS_HZ)
        x[start : start + n] += 0.5 * burst / burst.std()
    return x


@pytest.mark.parametrize("make_noise", [fan, door_slam, typing, cough],
                         ids=["fan", "door-slam", "typing", "cough"])
def test_non_speech_never_makes_a_speech_window(make_noise):
    x = make_noise(np.random.default_rng(3))
    detector = SpeechDetector(FS_HZ)
    features = detector.features(x)
    windows = [detector.window_is_speech(features, s, s + 0.5) for s in np.arange(0, 3.5, 0.1)]
    assert not any(windows)


@pytest.mark.parametrize("snr_db", [30.0, 10.0])
def test_speech_windows_are_found(snr_db):
    speech = synthetic_speech(DURATION_S, FS_HZ, seed=4)
    rng = np.random.default_rng(0)
    noise_std = np.sqrt(np.mean(speech.samples[speech.active] ** 2) / 10 ** (snr_db / 10))
    x = speech.samples + noise_std * rng.standard_normal(speech.samples.size)
    detector = SpeechDetector(FS_HZ)
    features = detector.features(x)
    starts = np.arange(0.0, DURATION_S - 0.5, 0.1)
    truth = [speech.active[int(s * FS_HZ) : int((s + 0.5) * FS_HZ)].mean() > 0.5 for s in starts]
    found = [detector.window_is_speech(features, s, s + 0.5) for s in starts]
    hits = sum(f for f, t in zip(found, truth, strict=True) if t)
    assert hits >= 0.9 * sum(truth)


def test_speech_over_a_running_fan_is_still_speech():
    rng = np.random.default_rng(8)
    speech = synthetic_speech(DURATION_S, FS_HZ, seed=9)
    x = fan(rng) * 0.5 + speech.samples
    detector = SpeechDetector(FS_HZ)
    features = detector.features(x)
    voiced_truth = features.voiced[features.times_s > 1.0]
    assert voiced_truth.mean() > 0.3


def test_bad_settings_are_config_errors():
    with pytest.raises(ConfigError, match="pitch_range_hz"):
        VadSettings(pitch_range_hz=(500.0, 100.0))
