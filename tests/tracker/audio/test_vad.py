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


@pytest.mark.parametrize("causal", [True, False])
@pytest.mark.parametrize("snr_db", [30.0, 10.0])
def test_speech_windows_are_found(snr_db, causal):
    detector = SpeechDetector(FS_HZ, VadSettings(causal=causal))
    hits, speech_windows = 0, 0
    for seed in range(4, 8):
        speech = synthetic_speech(DURATION_S, FS_HZ, seed=seed)
        rng = np.random.default_rng(seed)
        noise_std = np.sqrt(np.mean(speech.samples[speech.active] ** 2) / 10 ** (snr_db / 10))
        x = speech.samples + noise_std * rng.standard_normal(speech.samples.size)
        features = detector.features(x)
        starts = np.arange(0.0, DURATION_S - 0.5, 0.1)
        truth = [speech.active[int(s * FS_HZ) : int((s + 0.5) * FS_HZ)].mean() > 0.5
                 for s in starts]
        found = [detector.window_is_speech(features, s, s + 0.5) for s in starts]
        hits += sum(f for f, t in zip(found, truth, strict=True) if t)
        speech_windows += sum(truth)
    assert hits >= 0.9 * speech_windows


def test_causal_decisions_do_not_wait_for_the_future():
    """A causal detector decides each frame from the past (and the frame) only: cutting the
    signal right after a frame leaves its decision unchanged, so a live system has it when
    the frame ends (``lookahead_samples``)."""
    speech = synthetic_speech(DURATION_S, FS_HZ, seed=5)
    x = speech.samples + 0.01 * np.random.default_rng(1).standard_normal(speech.samples.size)
    detector = SpeechDetector(FS_HZ)
    full = detector.features(x)
    assert detector.lookahead_samples == detector.frame
    for cut_s in (0.7, 1.33, 2.5, 3.1):
        n = int(cut_s * FS_HZ)
        part = detector.features(x[:n])
        known = full.times_s * FS_HZ + detector.frame / 2 <= n
        assert np.array_equal(part.voiced[known[: part.voiced.size]], full.voiced[known])
    # The older, non-causal rule does depend on the future:
    older = SpeechDetector(FS_HZ, VadSettings(causal=False))
    assert older.lookahead_samples > 0.25 * FS_HZ


def test_a_machine_tone_switched_on_is_not_speech():
    """A pitched tone (blade-pass whine with harmonics) that rises in level like a syllable
    onset but holds its pitch is rejected once a few pitched frames show its pitch standing
    still: no analysis window (0.3 s, as in the meeting) becomes speech."""
    t = np.arange(int(DURATION_S * FS_HZ)) / FS_HZ
    tone = sum(np.sin(2 * np.pi * 220.0 * k * t) for k in range(1, 10))
    x = 0.001 * np.random.default_rng(2).standard_normal(t.size)
    on = t >= 1.0
    x[on] += 0.1 * tone[on] * np.minimum(1.0, (t[on] - 1.0) / 0.05)
    detector = SpeechDetector(FS_HZ)
    features = detector.features(x)
    windows = [detector.window_is_speech(features, s, s + 0.3) for s in np.arange(0, 3.7, 0.02)]
    assert not any(windows)


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


@pytest.mark.parametrize("block", [160, 1234, 4000])
def test_the_streaming_detector_measures_each_frame_once_and_decides_as_the_batch(block):
    """Speed (issue 12): a stream no longer re-measures 3 s of audio at every block; block by
    block, each frame is measured once (the low-pass's input history carried over) and the decisions are
    the whole signal's, also after forgetting frames older than the detector's history."""
    from tracker.audio.vad import StreamingSpeechDetector

    rng = np.random.default_rng(3)
    mono = np.concatenate([_room_noise(rng), synthetic_speech(DURATION_S, FS_HZ, seed=2).samples
                           + _room_noise(rng)])
    detector = SpeechDetector(FS_HZ)
    batch = detector.features(mono)
    everything, trimmed = StreamingSpeechDetector(detector), StreamingSpeechDetector(detector)
    for lo in range(0, mono.size, block):
        everything.push(mono[lo : lo + block])
        trimmed.push(mono[lo : lo + block])
        n = trimmed.frames_measured
        recent = trimmed.features()
        if recent.times_s.size:
            k = np.searchsorted(batch.times_s, recent.times_s[0])
            np.testing.assert_array_equal(recent.voiced[-20:], batch.voiced[k : k + len(recent.voiced)][-20:])
        trimmed.forget_before(n * detector.hop - detector.history_samples)
    whole = everything.features()
    for name in ("times_s", "level_db", "floor_db", "speech_band", "modulation_db", "voiced"):
        np.testing.assert_array_equal(getattr(whole, name), getattr(batch, name), err_msg=name)
    # The low-pass is an FFT convolution: blocks round differently from the whole signal.
    np.testing.assert_allclose(whole.harmonicity, batch.harmonicity, rtol=0, atol=1e-12)
    assert batch.voiced.any() and not batch.voiced.all()
