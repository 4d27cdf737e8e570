"""CPU of the streaming localizer per room: ms of CPU per second of audio, and % of one core.

The console streams each room's array through ``StreamingLocator`` in 0.1 s blocks with the
meeting settings (``app.audio.meeting_pipeline``: srp_phat over -90°..90°, 0.3 s windows every
0.1 s, the map tracker). This runs that pipeline, and the same windows with the Kalman tracker
(which also localizes 1.5 s windows), on a simulated meeting (the meeting scenario's room,
4-mic square, 16 kHz), streamed and in one batch, CPU time best of ``--repeat``.

Run: .venv/bin/python bench/bench_stream.py [--duration 60] [--repeat 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from tracker.audio.pipeline import Pipeline
from tracker.audio.stream import StreamingLocator, stream_blocks

ROOT = Path(__file__).resolve().parent.parent


def meeting_audio(duration_s: float, seed: int) -> tuple[int, np.ndarray]:
    """The simulated meeting (the console's default input) for the shipped 4-mic square."""
    from app.audio import load_meeting_array
    from tracker.scenarios.meeting import MeetingSettings, build_meeting

    recording, _ = build_meeting(seed, duration_s, MeetingSettings(), load_meeting_array())
    return int(recording.fs_hz), np.asarray(recording.audio)


def cpu_s(run: object, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        run()  # type: ignore[operator]
        best = min(best, time.process_time() - t0)
    return float(best)


def main() -> int:
    from app.audio import meeting_pipeline

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    fs, audio = meeting_audio(args.duration, args.seed)
    console = meeting_pipeline(fs)
    setups = {"console (map tracker)": console,
              "Kalman tracker, 1.5 s windows": dataclasses.replace(console, tracker="kalman")}
    block = int(0.1 * fs)
    duration = audio.shape[1] / fs
    print(f"simulated meeting {duration:.0f} s, {console.array.n_mics} mics, {fs} Hz, "
          f"{console.method}, windows {console.windows.window_s} s every "
          f"{console.windows.hop_s} s, 0.1 s blocks")
    for label, pipeline in setups.items():
        def stream(p: Pipeline = pipeline) -> StreamingLocator:
            locator = StreamingLocator(p)
            stream_blocks(locator, (audio[:, i : i + block] for i in range(0, audio.shape[1], block)))
            return locator

        stream()  # warm up (compiled kernels, FFT plans)
        locator_cpu = min(stream().compute_s for _ in range(args.repeat))
        batch = cpu_s(lambda p=pipeline: p.run(audio), args.repeat)
        print(f"{label:30s} streaming {1000 * locator_cpu / duration:6.1f} ms CPU per s "
              f"({100 * locator_cpu / duration:4.1f} % of a core); batch "
              f"{1000 * batch / duration:6.1f} ms per s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
