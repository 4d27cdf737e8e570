"""CPU of the streaming localizer: ms of CPU per second of audio (meeting settings, 4 mics, 16 kHz).

Run: .venv/bin/python bench/bench_stream.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from tracker.audio.array import load_array
from tracker.audio.pipeline import Pipeline
from tracker.audio.speech import synthetic_speech
from tracker.audio.stream import StreamingLocator, stream_blocks
from tracker.scenarios.meeting import MeetingSettings

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    ms = MeetingSettings()
    array = load_array(ROOT / "examples" / "arrays" / ms.array_file)
    fs = 16000
    duration_s = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
    rng = np.random.default_rng(0)
    speech = synthetic_speech(duration_s, fs, seed=0).samples
    audio = speech[None, :] + 0.01 * rng.standard_normal((array.n_mics, speech.size))
    opts = {"azimuth_range_rad": (-np.pi / 2, np.pi / 2)}

    def pipe() -> Pipeline:
        return Pipeline(array, fs, ms.method, ms.windows, tracking=ms.tracking,
                        localizer_options=opts)

    stream_blocks(StreamingLocator(pipe()), [audio[:, : 3 * fs]])  # warm up (numba, FFT plans)
    t0 = time.process_time()
    pipe().run(audio)
    batch_s = time.process_time() - t0
    loc = StreamingLocator(pipe())
    block = int(0.1 * fs)
    stream_blocks(loc, (audio[:, i : i + block] for i in range(0, audio.shape[1], block)))
    print(f"audio {duration_s:.0f} s, {array.n_mics} mics, {fs} Hz, {ms.method}, "
          f"windows {ms.windows.window_s}/{ms.windows.fine_window_s} s every {ms.windows.hop_s} s")
    print(f"batch pipeline : {1000 * batch_s / duration_s:7.1f} ms CPU per s of audio")
    print(f"streaming      : {1000 * loc.compute_s / duration_s:7.1f} ms CPU per s of audio "
          f"(0.1 s blocks)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
