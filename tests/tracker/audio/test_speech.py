"""Speech for simulations: the generator is deterministic and voice-like; espeak-ng when present."""

from __future__ import annotations

import numpy as np
import pytest

from tracker.audio.speech import espeak_available, espeak_speech, synthetic_speech
from tracker.audio.vad import SpeechDetector


def test_generator_is_deterministic_and_seed_dependent():
    a = synthetic_speech(2.0, 16000, seed=7)
    b = synthetic_speech(2.0, 16000, seed=7)
    c = synthetic_speech(2.0, 16000, seed=8)
    np.testing.assert_array_equal(a.samples, b.samples)
    assert not np.allclose(a.samples[:16000], c.samples[:16000])
    assert a.samples.shape == (32000,) and 0.4 < a.active.mean() < 0.95


@pytest.mark.parametrize("pitch_hz", [100.0, 200.0])
def test_generator_pitch_is_where_asked(pitch_hz):
    speech = synthetic_speech(3.0, 16000, seed=1, pitch_hz=pitch_hz)
    detector = SpeechDetector(16000)
    features = detector.features(speech.samples)
    assert features.voiced.mean() > 0.3
    spectrum = np.abs(np.fft.rfft(speech.samples * np.hanning(speech.samples.size)))
    freqs = np.fft.rfftfreq(speech.samples.size, 1 / 16000)
    band = (freqs > 60) & (freqs < 300)
    # The strongest low harmonic is the fundamental, within the phrase declination (+10/-15 %).
    f0 = freqs[band][np.argmax(spectrum[band])]
    assert 0.8 * pitch_hz < f0 < 1.2 * pitch_hz


@pytest.mark.skipif(not espeak_available(), reason="espeak-ng not installed")
def test_espeak_speech_has_the_asked_length():
    speech = espeak_speech(4.0, 16000, seed=2)
    assert speech.samples.shape == (64000,) and speech.active.mean() > 0.5
    assert np.sqrt(np.mean(speech.samples[speech.active] ** 2)) == pytest.approx(0.1, rel=1e-6)
