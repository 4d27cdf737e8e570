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
