"""Audio sources: WAV round trip, simulated room blocks, live capture failing cleanly."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from tracker.audio.capture import LiveCapture
from tracker.audio.sources import WavSource, read_wav, write_wav
from tracker.errors import DriverFault


def test_importing_audio_does_not_import_sounddevice():
    code = ("import sys, tracker.audio.sources, tracker.audio.capture, tracker.audio.pipeline, "
            "tracker.cli.audio; "
            "print('sounddevice' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def _portaudio_usable() -> bool:
    try:
        import sounddevice

        return len(sounddevice.query_devices()) > 0
    except (ImportError, OSError):
        return False


@pytest.mark.skipif(_portaudio_usable(), reason="a real PortAudio device exists here")
def test_live_capture_without_portaudio_or_device_is_a_driver_fault():
    with pytest.raises(DriverFault, match="PortAudio|audio input device|sounddevice"):
        LiveCapture(4)


def test_wav_roundtrip_and_blocks(tmp_path):
    audio = 0.5 * np.sin(np.arange(3 * 8000)[None, :] * np.array([[0.01], [0.02], [0.03]]))
    path = tmp_path / "three.wav"
    write_wav(path, 8000, audio)
    fs_hz, back = read_wav(path)
    assert fs_hz == 8000 and back.shape == (3, 24000)
    np.testing.assert_allclose(back, audio, atol=1e-4)
    source = WavSource(path)
    blocks = list(source.blocks(1.0))
    assert source.n_channels == 3 and len(blocks) == 3 and blocks[0].shape == (3, 8000)


def _wav_24bit(path, fs_hz, samples):
    """A 24-bit PCM file (scipy cannot write one) through the standard library."""
    import wave

    raw = np.asarray(samples, dtype="<i4").reshape(-1)
    triples = raw.view(np.uint8).reshape(-1, 4)[:, :3]
    with wave.open(str(path), "wb") as out:
        out.setnchannels(samples.shape[1])
        out.setsampwidth(3)
        out.setframerate(fs_hz)
        out.writeframes(np.ascontiguousarray(triples).tobytes())


@pytest.mark.parametrize("dtype", ["uint8", "int16", "int32", "float32", "float64", "int24"])
def test_read_wav_gives_what_scipy_reads(tmp_path, dtype):
    """read_wav parses RIFF itself (scipy.io costs a third of a second to import): the same
    samples as scipy.io.wavfile.read, scaled as before, for every format it writes."""
    from scipy.io import wavfile

    rng = np.random.default_rng(3)
    path = tmp_path / f"{dtype}.wav"
    noise = rng.uniform(-0.9, 0.9, (1001, 3))
    if dtype == "int24":
        _wav_24bit(path, 22050, np.round(noise * (2**23 - 1)).astype(np.int32))
    elif dtype == "uint8":
        wavfile.write(path, 22050, np.round(noise * 127 + 128).astype(np.uint8))
    elif dtype.startswith("int"):
        wavfile.write(path, 22050, np.round(noise * np.iinfo(dtype).max).astype(dtype))
    else:
        wavfile.write(path, 22050, noise.astype(dtype))
    fs_ref, ref = wavfile.read(path)
    if ref.dtype == np.uint8:
        expected = (ref.astype(float) - 128.0) / 128.0
    elif np.issubdtype(ref.dtype, np.integer):
        expected = ref.astype(float) / float(np.iinfo(ref.dtype).max)
    else:
        expected = ref.astype(float)
    fs_hz, audio = read_wav(path)
    assert fs_hz == fs_ref == 22050
    np.testing.assert_array_equal(audio, expected.T)


def test_read_wav_refuses_what_is_not_a_wav_file(tmp_path):
    from tracker.errors import DataError

    text = tmp_path / "notes.wav"
    text.write_text("not audio at all")
    with pytest.raises(DataError, match="notes.wav: not a readable WAV file"):
        read_wav(text)
    with pytest.raises(DataError, match="file not found"):
        read_wav(tmp_path / "missing.wav")
    cut = tmp_path / "cut.wav"
    write_wav(cut, 8000, np.zeros((2, 10)))
    cut.write_bytes(cut.read_bytes()[:40])  # the data chunk's header cut off
    with pytest.raises(DataError, match="cut.wav: not a readable WAV file \\(no data chunk\\)"):
        read_wav(cut)
