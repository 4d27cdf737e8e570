"""Benchmark: our localizers vs pyroomacoustics' SRP and NormMUSIC on the same simulated rooms.

Prints, per condition and method, the number of windows scored, the median and 90th-percentile
azimuth error and the share of errors over 10° on 1 s windows (windows where the talker speaks
at least half the time; at the target condition also on 0.3 s windows) and the milliseconds of CPU per
second of audio (inside the sweep, so on a shared machine; a best-of-5 speed table follows); then
the tracking figure: the share of speech frames whose tracked direction
is more than 20° off, for a talker who stands, then walks.

    .venv/bin/python bench/bench_audio.py            # target condition + a reduced sweep (~3 min)
    .venv/bin/python bench/bench_audio.py --full     # RT60 0.2-0.8 s x SNR 0-30 dB x placement
    .venv/bin/python bench/bench_audio.py --espeak   # espeak-ng sentences instead of the generator

Rooms: 6 x 5 x 3 m shoebox, pyroomacoustics image sources to order 10 plus a diffuse tail of
the requested RT60 (tracker.audio.room), independent white noise at the given SNR, the 4-mic
6.5 cm square (examples/arrays/square4_65mm.json) at 16 kHz, talkers 1-4.5 m away. Near the
wall the array is 0.15 m from it; the SRP methods and pyroomacoustics search the front
half-plane (``--front-only``, what a wall-mounted array calls for), and the SRP methods are
also scored over the whole circle (``srp_phat 360°``). At the target condition the same
recordings are also cut into 0.3 s windows (``--short-window-s``), the meeting's short window.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyroomacoustics as pra

from tracker.audio import room
from tracker.audio.array import MicArray, load_array
from tracker.audio.localizers import make_localizer
from tracker.audio.pipeline import Pipeline, WindowSettings
from tracker.audio.speech import espeak_available, synthetic_speech, talker_speech

FS_HZ = 16000
ARRAY_FILE = Path(__file__).resolve().parents[1] / "examples" / "arrays" / "square4_65mm.json"
OURS = ("seed_rms", "gcc_phat", "srp_phat", "srp_dpd")
PRA = ("SRP", "NormMUSIC")


@dataclass(frozen=True)
class Condition:
    rt60_s: float
    snr_db: float
    placement: str  # "wall" or "centre"

    @property
    def label(self) -> str:
        return f"RT60 {self.rt60_s:.1f} s, SNR {self.snr_db:>2.0f} dB, {self.placement}"


class PraMethod:
    """pyroomacoustics DOA object behind the same ``locate`` call, on the same STFT size."""

    def __init__(self, name: str, array: MicArray, front_only: bool, band_hz: tuple[float, float]):
        step = np.deg2rad(1.0)
        grid = (np.arange(-np.pi / 2, np.pi / 2 + step / 2, step) if front_only
                else np.arange(-np.pi, np.pi, step))
        self.doa = pra.doa.algorithms[name](array.positions_m[:, :2].T, FS_HZ, 512, c=343.0,
                                            num_src=1, azimuth=grid)
        self.band_hz = list(band_hz)

    def locate(self, frame: np.ndarray) -> float:
        spectra = pra.transform.stft.analysis(frame.T, 512, 256).transpose([2, 1, 0])
        self.doa.locate_sources(spectra, freq_range=self.band_hz)
        return float(self.doa.azimuth_recon[0])


def angle_error_deg(a: float, b: float) -> float:
    return float(abs(np.rad2deg(np.angle(np.exp(1j * (a - b))))))


def random_talker_position(placement: room.Placement, settings: room.RoomSettings,
                           rng: np.random.Generator, wall: bool) -> np.ndarray:
    """A mouth position 1-4.5 m away, inside the room with 0.4 m clearance."""
    size = np.array(settings.size_m)
    for _ in range(1000):
        az = rng.uniform(-75, 75) if wall else rng.uniform(-180, 180)
        d = rng.uniform(1.0, 4.5)
        point = room.position_from_direction(placement, np.deg2rad(az), d, rng.uniform(1.1, 1.7))
        if np.all(point[:2] > 0.4) and np.all(point[:2] < size[:2] - 0.4):
            return point
    raise RuntimeError("no talker position fits the room")


def condition_methods(array: MicArray, wall: bool, pra_band: tuple[float, float]
                      ) -> dict[str, object]:
    """The methods compared in one condition, by label.

    Near a wall the SRP methods and pyroomacoustics search the front half-plane (what a user
    does for a wall-mounted array: ``--front-only``); the SRP methods also run over the whole
    circle (label ``... 360°``) to show what the wall's mirror image costs without it.
    """
    front = {"azimuth_range_rad": (-np.pi / 2, np.pi / 2)} if wall else {}
    methods: dict[str, object] = {}
    for name in OURS:
        options = front if name in ("srp_phat", "srp_dpd") else {}
        methods[name] = make_localizer(name, array, FS_HZ, **options)
        if wall and options:
            methods[f"{name} 360°"] = make_localizer(name, array, FS_HZ)
    for name in PRA:
        methods[f"pra_{name}"] = PraMethod(name, array, wall, pra_band)
    warm_up = np.random.default_rng(0).standard_normal((array.n_mics, FS_HZ))
    for method in methods.values():  # compile / load numba caches outside the timing
        method.locate(warm_up)  # type: ignore[attr-defined]
    return methods


Results = dict[tuple[str, float], tuple[list[float], float, float]]


def run_condition(cond: Condition, array: MicArray, n_trials: int, seed: int,
                  pra_band: tuple[float, float], espeak: bool = False,
                  short_window_s: float | None = None) -> Results:
    """Errors and compute time per method and window length.

    Every trial is 4 s of one talker's speech; each method sees the 1 s windows (and, with
    ``short_window_s``, the consecutive windows of that length) in which the talker is active
    at least half the time. Returns (label, window_s) -> (errors_deg, cpu_s, audio_s).
    """
    settings = room.RoomSettings(rt60_s=cond.rt60_s, snr_db=cond.snr_db, fs_hz=FS_HZ)
    wall = cond.placement == "wall"
    placement = room.wall_placement(settings) if wall else room.centre_placement(settings)
    methods = condition_methods(array, wall, pra_band)
    windows_s = [1.0] if not short_window_s else [1.0, short_window_s]
    results: Results = {(name, w): ([], 0.0, 0.0) for w in windows_s for name in methods}
    rng = np.random.default_rng(seed)
    for trial in range(n_trials):
        speech = talker_speech(4.0, FS_HZ, seed * 1000 + trial, use_espeak=espeak)
        position = random_talker_position(placement, settings, rng, wall)
        recording = room.simulate(settings, array, placement,
                                  [room.static_talker(speech.samples, speech.active, position)],
                                  seed=seed * 1000 + trial)
        truth = float(recording.directions(np.array([0.0]))[0, 0, 0])
        for window_s in windows_s:
            length = int(round(window_s * FS_HZ))
            n_windows = recording.audio.shape[1] // length
            centres = (np.arange(n_windows) + 0.5) * length / FS_HZ
            talking = recording.activity(centres, window_s=window_s)[0] >= 0.5
            for k in np.flatnonzero(talking):
                frame = recording.audio[:, k * length : (k + 1) * length]
                for name, method in methods.items():
                    errors, seconds, audio_s = results[(name, window_s)]
                    start = time.process_time()
                    out = method.locate(frame)  # type: ignore[attr-defined]
                    seconds += time.process_time() - start
                    azimuth = out if isinstance(out, float) else out.azimuth_rad
                    errors.append(angle_error_deg(azimuth, truth))
                    results[(name, window_s)] = (errors, seconds, audio_s + window_s)
    return results


def speed_table(array: MicArray, pra_band: tuple[float, float]) -> None:
    """Best-of-5 CPU time per second of audio on one 1 s window.

    CPU time of this process (``time.process_time``), so other jobs on a shared machine do
    not inflate it; BLAS threads are not involved in these methods.
    """
    settings = room.RoomSettings(rt60_s=0.4, snr_db=10.0, fs_hz=FS_HZ)
    placement = room.wall_placement(settings)
    speech = synthetic_speech(1.0, FS_HZ, seed=5)
    position = room.position_from_direction(placement, np.deg2rad(20.0), 2.0)
    frame = room.simulate(settings, array, placement,
                          [room.static_talker(speech.samples, speech.active, position)]).audio
    methods: dict[str, object] = {name: make_localizer(name, array, FS_HZ) for name in OURS}
    methods.update({f"pra_{name}": PraMethod(name, array, False, pra_band) for name in PRA})
    print("speed (CPU time), 4 mics at 16 kHz, full azimuth circle, best of 5 runs of 5 calls on 1 s:")
    for name, method in methods.items():
        best = np.inf
        for _ in range(5):
            start = time.process_time()
            for _ in range(5):
                method.locate(frame)
            best = min(best, (time.process_time() - start) / 5)
        print(f"  {name:14s} {1000 * best:7.2f} ms per second of audio = {1.0 / best:7.0f}x real time")


def tracking_error_share(array: MicArray, n_runs: int, seed: int) -> tuple[float, float, int]:
    """Share of speech frames (%) with tracked direction > 20° off, at the target condition.

    Each run: 20 s of speech, the talker stands for 8 s, walks 2 m sideways over 6 s, stands.
    Returns (share over all speech frames after the first framing, raw-frame share, n_frames).
    """
    settings = room.RoomSettings(rt60_s=0.4, snr_db=10.0, fs_hz=FS_HZ)
    placement = room.wall_placement(settings)
    pipeline = Pipeline(array, FS_HZ, "srp_phat", WindowSettings(0.3, 0.1, 1.5),
                        localizer_options={"azimuth_range_rad": (-np.pi / 2, np.pi / 2)})
    rng = np.random.default_rng(seed)
    bad = raw_bad = total = 0
    for run in range(n_runs):
        speech = synthetic_speech(20.0, FS_HZ, seed=seed * 77 + run)
        x0, y0 = rng.uniform(1.5, 3.5), rng.uniform(1.0, 2.0)
        start = np.array([x0, y0, 1.5])
        end = np.array([x0, y0 + 2.0, 1.5])
        talker = room.Talker(speech.samples, speech.active, np.array([0.0, 8.0, 14.0, 20.0]),
                             np.stack([start, start, end, end]))
        recording = room.simulate(settings, array, placement, [talker], seed=run)
        result = pipeline.run(recording.audio)
        times = np.array([f.t_s for f in result.frames])
        truth = recording.directions(times)[0, :, 0]
        speaking = recording.activity(times, window_s=0.3)[0] >= 0.5
        framed = np.array([p.shot != "none" for p in result.track])
        first = np.argmax(framed) if framed.any() else len(framed)
        mask = speaking & (np.arange(len(times)) >= first)
        tracked = np.array([p.azimuth_rad for p in result.track])
        raw = np.array([f.azimuth_rad for f in result.frames])
        err = np.abs(np.angle(np.exp(1j * (tracked - truth))))[mask]
        raw_err = np.abs(np.angle(np.exp(1j * (raw - truth))))[mask]
        bad += int(np.sum(err > np.deg2rad(20)))
        raw_bad += int(np.sum(raw_err > np.deg2rad(20)))
        total += int(mask.sum())
    return 100.0 * bad / max(total, 1), 100.0 * raw_bad / max(total, 1), total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="the whole RT60 x SNR x placement grid")
    parser.add_argument("--trials", type=int, default=120,
                        help="talker positions at the target condition (120: about 430 1 s windows)")
    parser.add_argument("--sweep-trials", type=int, default=40,
                        help="positions per sweep condition (40: about 140 windows)")
    parser.add_argument("--tracking-runs", type=int, default=6)
    parser.add_argument("--pra-band", type=float, nargs=2, default=(300.0, 3500.0),
                        help="frequency range given to pyroomacoustics (Hz)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--short-window-s", type=float, default=0.3,
                        help="also score windows this long at the target condition (0: off)")
    parser.add_argument("--espeak", action="store_true",
                        help="speech from espeak-ng (must be installed) instead of the generator")
    args = parser.parse_args()
    if args.espeak and not espeak_available():
        parser.error("--espeak needs espeak-ng on PATH (apt-get install espeak-ng)")
    array = load_array(ARRAY_FILE)
    conditions = [(Condition(0.4, 10.0, "wall"), args.trials)]
    if args.full:
        grid = [Condition(r, s, p) for p in ("wall", "centre") for r in (0.2, 0.4, 0.6, 0.8)
                for s in (0.0, 10.0, 20.0, 30.0)]
        conditions += [(c, args.sweep_trials) for c in grid if c != conditions[0][0]]
    else:
        conditions += [(Condition(r, s, p), args.sweep_trials)
                       for r, s, p in ((0.2, 30.0, "centre"), (0.4, 10.0, "centre"),
                                       (0.8, 10.0, "wall"), (0.4, 0.0, "wall"),
                                       (0.8, 0.0, "centre"))]
    voice = "espeak-ng" if args.espeak else "synthetic voiced speech"
    print(f"{voice}; array {ARRAY_FILE.name} (4 mics), fs {FS_HZ} Hz, 1 s windows (and "
          f"{args.short_window_s:.1f} s at the target condition); pyroomacoustics "
          f"{pra.__version__} band {args.pra_band[0]:.0f}-{args.pra_band[1]:.0f} Hz")
    header = (f"{'condition':34s} {'method':16s} {'window':>6s} {'windows':>7s} {'median°':>8s} "
              f"{'p90°':>7s} {'>10°':>6s} {'ms/s':>7s}")
    print(header)
    print("-" * len(header))
    wall_clock = time.perf_counter()
    for index, (cond, n_trials) in enumerate(conditions):
        short = args.short_window_s if index == 0 else None
        results = run_condition(cond, array, n_trials, args.seed + index, tuple(args.pra_band),
                                args.espeak, short)
        for (name, window_s), (errors, seconds, audio_s) in results.items():
            errors_arr = np.array(errors)
            print(f"{cond.label:34s} {name:16s} {window_s:5.1f}s {errors_arr.size:7d} "
                  f"{np.median(errors_arr):8.2f} {np.percentile(errors_arr, 90):7.2f} "
                  f"{100 * np.mean(errors_arr > 10):5.1f}% {1000 * seconds / audio_s:7.2f}")
        print()
    speed_table(array, tuple(args.pra_band))
    share, raw_share, n_frames = tracking_error_share(array, args.tracking_runs, args.seed)
    print(f"tracking (RT60 0.4 s, SNR 10 dB, wall; talker stands then walks; srp_phat 0.3 s "
          f"windows + 1.5 s refinement): {share:.2f} % of {n_frames} speech frames > 20° off "
          f"(raw 0.3 s estimates: {raw_share:.1f} %)")
    print(f"total {time.perf_counter() - wall_clock:.0f} s")


if __name__ == "__main__":
    main()
