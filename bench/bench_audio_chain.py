"""End-to-end speed of ``tracker audio locate``: real-time factor per stage, 4 and 8 mics.

Simulates a 60 s meeting (the meeting scenario's room: RT60 0.4 s, SNR 10 dB, array on the
wall, four talkers taking turns, one walking) for the 4-mic square and the 8-mic circle,
writes it as a 16 kHz WAV and runs the chain the command runs, timing each stage in CPU
seconds (best of ``--repeat``):

    read WAV -> speech detection -> spectra (STFT frames) -> localizer -> tracker -> JSON

for four set-ups: ``locate`` defaults (0.5 s windows every 0.1 s, full circle, the map
tracker on a circular grid), the same with ``--tracker kalman`` (which also localizes the
1.5 s long windows of speech windows), ``locate --front-only`` and the console's meeting
settings (0.3 s windows over -90°..90°, the map tracker). The real-time factor is audio seconds over
CPU seconds. Then the start-up of ``tracker --help``, of a small command and of the imports the
locate chain needs (median wall time of several subprocess runs), and the whole ``tracker audio
locate`` command from WAV to JSON: median wall time and median CPU time (user + system) of
``--runs`` runs, each as a real-time factor. The machine is shared: the load average is printed
beside the figures (a busy machine inflates wall time far more than CPU time).

    .venv/bin/python bench/bench_audio_chain.py [--duration 60] [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the command line sets it

import numpy as np  # noqa: E402

from tracker.audio.array import MicArray, load_array  # noqa: E402
from tracker.audio.localizers.frames import StftFrames  # noqa: E402
from tracker.audio.pipeline import Pipeline, WindowSettings, check_recording  # noqa: E402
from tracker.audio.sources import read_wav, write_wav  # noqa: E402
from tracker.audio.trackers import choose_tracker  # noqa: E402
from tracker.scenarios.meeting import MeetingSettings, build_meeting  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ARRAYS = {4: "square4_65mm", 8: "circular8_50mm"}
FRONT = (-np.pi / 2, np.pi / 2)


def setups(array: MicArray, fs_hz: int) -> dict[str, Pipeline]:
    """The pipelines of ``locate`` (its default tracker, and the Kalman one), ``locate
    --front-only`` and the console."""
    def pipe(window_s: float, front: bool, tracker: str | None = None) -> Pipeline:
        options = {"azimuth_range_rad": FRONT} if front else {}
        return Pipeline(array, fs_hz, "srp_phat", WindowSettings(window_s, 0.1, 1.5),
                        localizer_options=options,
                        tracker=tracker or choose_tracker("srp_phat"))  # type: ignore[arg-type]

    return {"locate": pipe(0.5, False), "locate --tracker kalman": pipe(0.5, False, "kalman"),
            "locate --front-only": pipe(0.5, True), "console (0.3 s, map)": pipe(0.3, True)}


class _SpectraClock:
    """Adds the CPU time spent computing STFT frames (wraps ``StftFrames.add``)."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self._add = StftFrames.add

    def __enter__(self) -> _SpectraClock:
        clock, add = self, self._add

        def timed(frames: StftFrames, *args: object) -> None:
            t0 = time.process_time()
            add(frames, *args)  # type: ignore[arg-type]
            clock.seconds += time.process_time() - t0

        StftFrames.add = timed  # type: ignore[method-assign, assignment]
        return self

    def __exit__(self, *exc: object) -> None:
        StftFrames.add = self._add  # type: ignore[method-assign]


def stage_seconds(path: Path, pipeline: Pipeline) -> dict[str, float]:
    """CPU seconds of each stage of one run of the chain."""
    out: dict[str, float] = {}
    t0 = time.process_time()
    fs_hz, audio = read_wav(path)
    audio = check_recording(audio, pipeline.array, fs_hz, pipeline.windows.window_s)
    t1 = time.process_time()
    starts, speech = pipeline.speech_windows(audio)
    t2 = time.process_time()
    with _SpectraClock() as spectra:
        frames = tuple(pipeline.estimate_windows(audio, 0, starts, speech))
    t3 = time.process_time()
    track = pipeline.track(frames)
    t4 = time.process_time()
    from tracker.audio.pipeline import LocateResult

    json.dumps(LocateResult(fs_hz, pipeline.method, frames, track).to_dict())
    t5 = time.process_time()
    out["read WAV"] = t1 - t0
    out["speech detection"] = t2 - t1
    out["spectra"] = spectra.seconds
    out["localizer"] = t3 - t2 - spectra.seconds
    out["tracker"] = t4 - t3
    out["JSON"] = t5 - t4
    out["total"] = t5 - t0
    return out


def wall_median(argv: list[str], runs: int) -> float:
    """Median wall time (s) of running ``argv`` in a subprocess."""
    return command_times(argv, runs)[0]


def command_times(argv: list[str], runs: int) -> tuple[float, float]:
    """Median wall time and median CPU time (user + system, s) of running ``argv``."""
    walls, cpus = [], []
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for _ in range(runs):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(argv, check=True, capture_output=True, env=env)
        walls.append(time.perf_counter() - t0)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


def load() -> str:
    """The 1, 5 and 15 minute load averages."""
    return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="seconds of meeting")
    parser.add_argument("--repeat", type=int, default=3, help="runs per set-up (best is kept)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--mics", type=int, nargs="+", default=sorted(ARRAYS), choices=sorted(ARRAYS))
    parser.add_argument("--chain-only", action="store_true", help="skip the start-up timings")
    parser.add_argument("--runs", type=int, default=7, help="runs of each whole command")
    parser.add_argument("--wav-dir", type=Path, default=None,
                        help="keep the simulated WAV files here (reused when present)")
    args = parser.parse_args()
    arrays = {n: ARRAYS[n] for n in args.mics}
    stages = ("read WAV", "speech detection", "spectra", "localizer", "tracker", "JSON", "total")
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.wav_dir or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        wavs = {}
        for n_mics, name in arrays.items():
            wavs[n_mics] = folder / f"meeting_{name}_{args.seed}_{args.duration:g}s.wav"
            if not wavs[n_mics].exists():
                array = load_array(ROOT / "examples" / "arrays" / f"{name}.json")
                recording, _ = build_meeting(args.seed, args.duration, MeetingSettings(), array)
                write_wav(wavs[n_mics], recording.fs_hz, recording.audio)
        print(f"{args.duration:.0f} s meeting, 16 kHz, srp_phat; real-time factor (audio s per "
              f"CPU s, best of {args.repeat}) per stage; ms of CPU in brackets; {load()}")
        print(f"{'mics':>4} {'set-up':22s} " + " ".join(f"{s:>17s}" for s in stages))
        for n_mics, name in arrays.items():
            array = load_array(ROOT / "examples" / "arrays" / f"{name}.json")
            fs_hz, audio = read_wav(wavs[n_mics])
            duration = audio.shape[1] / fs_hz
            for label, pipeline in setups(array, fs_hz).items():
                stage_seconds(wavs[n_mics], pipeline)  # warm up (compiled kernels, FFT plans)
                runs = [stage_seconds(wavs[n_mics], pipeline) for _ in range(args.repeat)]
                best = {s: min(r[s] for r in runs) for s in stages}
                cells = [f"{duration / max(best[s], 1e-9):8.0f}x ({1e3 * best[s]:5.0f})"
                         for s in stages]
                print(f"{n_mics:4d} {label:22s} " + " ".join(f"{c:>17s}" for c in cells))
        if args.chain_only:
            return 0
        python = sys.executable
        print(f"\nstart-up, median wall time of 7 runs ({load()}):")
        for argv in (["--help"], ["audio", "locate", "--help"], ["simulate", "--help"]):
            t = wall_median([python, "-m", "tracker", *argv], 7)
            print(f"  tracker {' '.join(argv):24s} {t:6.3f} s")
        chain = ("import tracker.cli.audio, tracker.audio.pipeline, tracker.audio.head, "
                 "tracker.audio.sources")
        t = wall_median([python, "-c", chain], 7)
        print(f"  imports of the locate chain         {t:6.3f} s (python and numpy included)")
        print(f"whole command, WAV to JSON, median of {args.runs} runs ({load()}):")
        for n_mics, name in arrays.items():
            array_file = str(ROOT / "examples" / "arrays" / f"{name}.json")
            for extra in ([], ["--front-only"]):
                argv = [python, "-m", "tracker", "audio", "locate", str(wavs[n_mics]),
                        "--array", array_file, "--json", *extra]
                wall, cpu = command_times(argv, args.runs)
                print(f"  tracker audio locate ({n_mics} mics{', --front-only' if extra else ''}): "
                      f"wall {wall:5.2f} s = {args.duration / wall:5.1f}x real time, "
                      f"CPU {cpu:5.2f} s = {args.duration / cpu:5.1f}x")
        print(f"({load()})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
