"""How much of the meeting score the camera itself costs: an oracle target through the twin.

The pan target is the active talker's true azimuth (sampled every hop, held, as the pipeline
does), available ``delay`` seconds after each turn starts; the real controller and twin follow
it and the meeting is scored as ``tracker simulate meeting`` scores it. With no delay this is
the ceiling the camera's dynamics allow; with the tracker's confirmation delay it shows what a
perfect localizer would score.

    .venv/bin/python bench/bench_meeting_camera.py [--seeds 0,1,2] [--delays 0,0.2,0.4,0.6]
"""

from __future__ import annotations

import argparse

import numpy as np

from tracker.audio.array import load_array
from tracker.scenarios.meeting import (
    _ARRAYS_DIR,
    _DT_S,
    MeetingSettings,
    _pan_response,
    build_meeting,
    score_meeting,
)


def oracle_target(truth_rad: np.ndarray, turns, times_s: np.ndarray, delay_s: float,
                  hop_s: float) -> np.ndarray:
    """Active talker's true azimuth from ``delay_s`` after each turn start, held per hop."""
    target = np.zeros_like(times_s)
    held = 0.0
    next_sample_s = 0.0
    for k, t in enumerate(times_s):
        if t >= next_sample_s:
            next_sample_s += hop_s
            current = [turn for turn in turns if turn.start_s + delay_s <= t]
            if current:
                held = float(truth_rad[current[-1].talker, k])
        target[k] = held
    return target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--delays", default="0,0.2,0.4,0.6")
    parser.add_argument("--duration", type=float, default=60.0)
    args = parser.parse_args()
    settings = MeetingSettings()
    array = load_array(_ARRAYS_DIR / settings.array_file)
    delays = [float(d) for d in args.delays.split(",")]
    print("delay_s  seed  on_target_%  time_to_frame_s  switches/changes per min")
    for seed in (int(s) for s in args.seeds.split(",")):
        recording, turns = build_meeting(seed, args.duration, settings, array)
        times = np.arange(int(round(args.duration / _DT_S))) * _DT_S
        truth = recording.directions(times)[:, :, 0]
        for delay in delays:
            target = oracle_target(truth, turns, times, delay, settings.windows.hop_s)
            pan, plant = _pan_response(target)
            per_hop = target[:: int(round(settings.windows.hop_s / _DT_S))]
            r = score_meeting(recording, turns, times, pan, per_hop, seed, plant)
            print(f"{delay:7.2f}  {seed:4d}  {r.on_target_percent:11.1f}  {r.time_to_frame_s:15.2f}"
                  f"  {r.switches_per_minute:.0f}/{r.talker_changes_per_minute:.0f}")


if __name__ == "__main__":
    main()
