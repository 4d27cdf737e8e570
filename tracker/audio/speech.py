"""Speech for simulations: a deterministic voiced-speech generator, and espeak-ng when installed."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy import signal
from scipy.io import wavfile

from tracker.errors import DriverFault

FloatArray = NDArray[np.float64]

# (F1, F2, F3) in Hz of five vowels for an adult voice (Peterson & Barney averages, rounded).
_VOWELS_HZ = np.array(
    [[730, 1090, 2440], [530, 1840, 2480], [270, 2290, 3010], [570, 840, 2410], [300, 870, 2240]],
    dtype=float,
)
_BANDWIDTHS_HZ = np.array([90.0, 110.0, 160.0, 250.0, 300.0])
# Higher formants barely move between vowels; they keep the spectrum above 3 kHz realistic.
_HIGH_FORMANTS_HZ = np.array([3300.0, 4200.0])

_SENTENCES = (
    "Good morning everyone, let us start with the budget for the next quarter.",
    "I think the prototype is ready for a first test in the meeting room.",
    "Could you share the numbers from last week before we decide?",
    "The camera should follow whoever is talking without any delay.",
    "We measured the friction on both axes and the model fits well.",
    "Let me walk over to the whiteboard and draw the block diagram.",
    "That sounds reasonable, but what happens when two people speak at once?",
    "Thank you, I will send the summary to the whole team this afternoon.",
)


@dataclass(frozen=True, slots=True, eq=False)
class Speech:
    """A mono speech signal with its ground-truth activity.

    Attributes
    ----------
    samples : ndarray, shape (n_samples,)
        Float samples, RMS about 0.1 while active.
    active : ndarray of bool, shape (n_samples,)
        True where the talker is producing sound (syllables, not the pauses between phrases).
    fs_hz : int
    """

    samples: FloatArray
    active: NDArray[np.bool_]
    fs_hz: int


def _resonator(freq_hz: float, bandwidth_hz: float, fs_hz: int) -> tuple[FloatArray, FloatArray]:
    """Second-order all-pole resonator with unit gain at DC; returns (b, a)."""
    r = np.exp(-np.pi * bandwidth_hz / fs_hz)
    a = np.array([1.0, -2.0 * r * np.cos(2 * np.pi * freq_hz / fs_hz), r * r])
    return np.array([a.sum()]), a


def _syllable(rng: np.random.Generator, fs_hz: int, f0_hz: float, length: int) -> FloatArray:
    """One voiced syllable: glottal pulses with a gliding pitch through five formants."""
    t = np.arange(length) / fs_hz
    glide = rng.uniform(-0.25, 0.25)
    f0 = f0_hz * (1.0 + glide * t / max(t[-1], 1e-3)) * (1.0 + 0.01 * rng.standard_normal())
    phase = np.cumsum(f0) / fs_hz
    pulses = np.zeros(length)
    pulses[np.flatnonzero(np.diff(np.floor(phase), prepend=0.0) > 0)] = 1.0
    # Glottal flow: two real poles give the -12 dB/octave source tilt; differencing adds lip radiation.
    source = signal.lfilter([1.0], [1.0, -1.9, 0.9025], pulses)
    source = np.diff(source, prepend=0.0)
    # Breathiness: a little aspiration noise, as in real voices.
    source = source + 0.05 * np.std(source) * rng.standard_normal(length)
    vowel = np.concatenate([_VOWELS_HZ[rng.integers(len(_VOWELS_HZ))] * rng.uniform(0.92, 1.08),
                            _HIGH_FORMANTS_HZ * rng.uniform(0.95, 1.05)])
    voiced = source
    for freq, bandwidth in zip(vowel, _BANDWIDTHS_HZ, strict=True):
        b, a = _resonator(freq, bandwidth, fs_hz)
        voiced = signal.lfilter(b, a, voiced)
    attack, release = int(0.03 * fs_hz), int(0.06 * fs_hz)
    envelope = np.ones(length)
    envelope[:attack] = np.linspace(0.0, 1.0, attack)
    envelope[-release:] = np.linspace(1.0, 0.0, release)
    voiced = voiced * envelope / (np.std(voiced) + 1e-12)
    if rng.random() < 0.5:  # a fricative onset
        n_fric = int(rng.uniform(0.03, 0.07) * fs_hz)
        sos = signal.butter(4, [2500.0, min(6500.0, 0.45 * fs_hz)], "bandpass", fs=fs_hz,
                            output="sos")
        fric = signal.sosfilt(sos, rng.standard_normal(n_fric)) * np.hanning(n_fric)
        voiced[:n_fric] += 0.4 * fric / (np.std(fric) + 1e-12)
    return np.asarray(voiced)


def synthetic_speech(duration_s: float, fs_hz: int = 16000, seed: int = 0,
                     pitch_hz: float | None = None) -> Speech:
    """Deterministic speech-like signal: phrases of syllables with pauses.

    Glottal pulse train (pitch 90-220 Hz, gliding within each syllable and declining over a
    phrase) through five formant resonators (three per vowel, two fixed higher ones),
    syllables of 120-300 ms at about 4 per second with fricative onsets, phrases of 1-3.5 s
    separated by 0.15-0.6 s pauses.

    Parameters
    ----------
    duration_s : float
    fs_hz : int
    seed : int
        Same seed, same signal.
    pitch_hz : float, optional
        The talker's mean pitch; drawn in 90-220 Hz from the seed when omitted.
    """
    rng = np.random.default_rng(seed)
    n_total = int(round(duration_s * fs_hz))
    samples = np.zeros(n_total)
    active = np.zeros(n_total, dtype=bool)
    base_pitch = pitch_hz if pitch_hz is not None else rng.uniform(90.0, 220.0)
    position = int(rng.uniform(0.0, 0.1) * fs_hz)
    while position < n_total:
        phrase_end = position + int(rng.uniform(1.0, 3.5) * fs_hz)
        declination = 1.1
        while position < min(phrase_end, n_total):
            length = int(rng.uniform(0.12, 0.30) * fs_hz)
            syllable = _syllable(rng, fs_hz, base_pitch * declination, length)
            declination = max(0.85, declination - 0.03)
            end = min(position + length, n_total)
            samples[position:end] += rng.uniform(0.6, 1.0) * syllable[: end - position]
            active[position:end] = True
            position = end + int(rng.uniform(0.02, 0.08) * fs_hz)
        position += int(rng.uniform(0.15, 0.6) * fs_hz)
    return Speech(_normalise(samples, active), active, fs_hz)


def espeak_available() -> bool:
    """True when the ``espeak-ng`` program is on PATH."""
    return shutil.which("espeak-ng") is not None


def espeak_speech(duration_s: float, fs_hz: int = 16000, seed: int = 0) -> Speech:
    """Sentences spoken by espeak-ng (voice and speed chosen by ``seed``) to ``duration_s``.

    Raises
    ------
    DriverFault
        espeak-ng is not installed or failed.
    """
    program = shutil.which("espeak-ng")
    if program is None:
        raise DriverFault("espeak-ng is not installed (apt-get install espeak-ng)")
    rng = np.random.default_rng(seed)
    voice = ["en+m1", "en+f2", "en+m3", "en+f4", "en-us+m2"][seed % 5]
    speed = str(int(rng.uniform(140, 175)))
    order = rng.permutation(len(_SENTENCES))
    n_sentences = max(1, min(12, int(duration_s / 3.0) + 1))  # about 3 s per sentence
    text = " ".join(_SENTENCES[k] for k in np.resize(order, n_sentences))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "speech.wav"  # a file: --stdout leaves the WAV length unset
        try:
            subprocess.run([program, "-v", voice, "-s", speed, "-w", str(path), text],
                           capture_output=True, check=True, timeout=60)
            rate, data = wavfile.read(path)
        except (OSError, ValueError, subprocess.SubprocessError) as exc:
            raise DriverFault(f"espeak-ng failed: {exc}") from exc
    mono = data.astype(float) / 32768.0
    if rate != fs_hz:
        g = np.gcd(int(rate), int(fs_hz))
        mono = signal.resample_poly(mono, fs_hz // g, int(rate) // g)
    n_total = int(round(duration_s * fs_hz))
    mono = np.resize(mono, n_total) if mono.size < n_total else mono[:n_total]
    frame = int(0.02 * fs_hz)
    energy = np.convolve(mono**2, np.ones(frame) / frame, mode="same")
    active = energy > 1e-3 * np.max(energy)
    return Speech(_normalise(mono, active), active, fs_hz)


def talker_speech(duration_s: float, fs_hz: int = 16000, seed: int = 0,
                  use_espeak: bool = False) -> Speech:
    """espeak-ng speech when asked for and installed, the synthetic generator otherwise."""
    if use_espeak and espeak_available():
        return espeak_speech(duration_s, fs_hz, seed)
    return synthetic_speech(duration_s, fs_hz, seed)


def _normalise(samples: FloatArray, active: NDArray[np.bool_]) -> FloatArray:
    """Scale to an RMS of 0.1 over the active samples."""
    rms = np.sqrt(np.mean(samples[active] ** 2)) if active.any() else 1.0
    return np.asarray(samples * (0.1 / max(rms, 1e-12)))
