"""The meeting scenario scored with the Kalman tracker and the map tracker on the same frames.

For each seed the audio is simulated once and localised once (short and long windows and the
short windows' azimuth maps, ``Pipeline(tracker="map")`` gives all three); both trackers then
run on those frames and drive the same camera twin. Prints per seed on-target %, time to frame,
switches / talker changes and where on-target time is lost, then the means of seeds 0-7 and
8-13 separately (tune on the first half, confirm on the second).

    .venv/bin/python bench/bench_meeting_trackers.py [--seeds 0-13] [--cache DIR]
        [--audio-cache DIR]

``--cache DIR`` keeps each seed's frames (with maps); ``--audio-cache DIR`` reads the audio
from ``bench_meeting.py``'s cache when it is there (``meeting_{seed}_{duration}.pkl``), so the
costly room simulation is not repeated. Delete the frame cache after changing a localizer or
the speech detector.
"""

from __future__ import annotations

import argparse
import pickle
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from tracker.audio import room
from tracker.audio.pipeline import FrameEstimate
from tracker.scenarios.meeting import MeetingSettings, Turn, build_meeting, camera_result

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_meeting import _seeds, breakdown  # noqa: E402


def _audio(seed: int, duration_s: float, settings: MeetingSettings, cache: Path | None
           ) -> tuple[room.Recording, tuple[Turn, ...]]:
    path = cache / f"meeting_{seed}_{duration_s:g}.pkl" if cache else None
    if path is not None and path.exists():
        with path.open("rb") as fh:
            recording, turns, _ = pickle.load(fh)
        return recording, tuple(turns)
    from tracker.audio.array import load_array
    from tracker.scenarios.meeting import _ARRAYS_DIR

    return build_meeting(seed, duration_s, settings, load_array(_ARRAYS_DIR / settings.array_file))


def _frames(seed: int, duration_s: float, recording: room.Recording, settings: MeetingSettings,
            cache: Path | None) -> tuple[FrameEstimate, ...]:
    path = cache / f"frames_{seed}_{duration_s:g}.pkl" if cache else None
    if path is not None and path.exists():
        with path.open("rb") as fh:
            cached: tuple[FrameEstimate, ...] = pickle.load(fh)
            return cached
    from tracker.audio.array import load_array
    from tracker.scenarios.meeting import _ARRAYS_DIR, _pipeline

    array = load_array(_ARRAYS_DIR / settings.array_file)
    # Both trackers on the same frames: the long windows too (the Kalman tracker reads them).
    frames = _pipeline(settings, array, recording.fs_hz, estimate_fine=True).estimate_frames(
        recording.audio)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as fh:
            pickle.dump(frames, fh)
    return frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-13")
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--cache", type=Path, default=None)
    parser.add_argument("--audio-cache", type=Path, default=None)
    parser.add_argument("--no-majority", action="store_true",
                        help="both trackers without their majority rules (for comparison)")
    args = parser.parse_args()
    base = replace(MeetingSettings(), tracker="map")
    if args.no_majority:
        base = replace(base, tracking=replace(base.tracking, majority_guard=False),
                       map_tracking=replace(base.map_tracking, majority_guard=False))
    trackers = {"kalman": replace(base, tracker="kalman"), "map": base}
    rows: dict[str, list[tuple[float, ...]]] = {name: [] for name in trackers}
    print("seed tracker  on_target_%  frame_s  switches/changes  jitter_deg | lost % of speech: "
          "framing seated walker")
    for seed in _seeds(args.seeds):
        recording, turns = _audio(seed, args.duration, base, args.audio_cache)
        frames = _frames(seed, args.duration, recording, base, args.cache)
        for name, settings in trackers.items():
            run = camera_result(recording, turns, frames, settings, seed)
            r, b = run.result, breakdown(recording, turns, run)
            sp = b["speech_s"]
            row = (seed, r.on_target_percent, r.time_to_frame_s, r.switches_per_minute,
                   r.talker_changes_per_minute, 100 * b["framing_s"] / sp,
                   100 * b["seated_after_s"] / sp, 100 * b["walker_after_s"] / sp,
                   r.pan_jitter_deg)
            rows[name].append(row)
            print(f"{seed:4d} {name:7s} {row[1]:11.1f}  {row[2]:7.2f}  {row[3]:7.0f}/{row[4]:<8.0f}"
                  f"{row[8]:6.2f}     | {row[5]:6.1f} {row[6]:6.1f} {row[7]:6.1f}", flush=True)
    for name, data in rows.items():
        a = np.array(data)
        for label, part in (("0-7", a[a[:, 0] <= 7]), ("8-13", a[a[:, 0] >= 8]), ("all", a)):
            if len(part):
                m = part.mean(axis=0)
                print(f"mean {name:7s} seeds {label:5s} on-target {m[1]:5.1f}  frame {m[2]:.2f} s  "
                      f"extra switches/min {m[3] - m[4]:+.2f}  jitter {m[8]:.2f}° | framing "
                      f"{m[5]:.1f} seated {m[6]:.1f} walker {m[7]:.1f}")


if __name__ == "__main__":
    main()
