"""Meeting scenario over several seeds, with where the on-target time is lost.

For each seed: the scores of ``tracker simulate meeting`` and a breakdown of the speech time the
camera was off the active talker: while framing a new talker (turn start to first on-target),
and after framing, for seated talkers and for the walker. Also the raw estimates' error
against the active talker (short and long window) on speech frames, to tell the localizer's
share from the tracker's.

    .venv/bin/python bench/bench_meeting.py [--seeds 0-5] [--duration 60] [--cache DIR]

``--cache DIR`` keeps each seed's audio and raw estimates (the costly part) so that tracker
changes can be re-scored in a few seconds; delete the folder after changing the room, the
speech, the speech detector or a localizer.
"""

from __future__ import annotations

import argparse
import pickle
import time
from pathlib import Path

import numpy as np

from tracker.audio import room
from tracker.audio.pipeline import FrameEstimate
from tracker.scenarios.meeting import (
    _DT_S,
    _ON_TARGET_RAD,
    _SEATS,
    CameraRun,
    MeetingSettings,
    Turn,
    camera_result,
    meeting_frames,
)


def _seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = (int(v) for v in text.split("-"))
        return list(range(lo, hi + 1))
    return [int(v) for v in text.split(",")]


MeetingData = tuple[room.Recording, tuple[Turn, ...], tuple[FrameEstimate, ...]]


def _frames(seed: int, duration_s: float, settings: MeetingSettings, cache: Path | None
            ) -> MeetingData:
    path = cache / f"meeting_{seed}_{duration_s:g}.pkl" if cache else None
    if path is not None and path.exists():
        with path.open("rb") as fh:
            cached: MeetingData = pickle.load(fh)
            return cached
    data = meeting_frames(seed, duration_s, settings, estimate_fine=True)  # long windows scored
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as fh:
            pickle.dump(data, fh)
    return data


def breakdown(recording: room.Recording, turns: tuple[Turn, ...], run: CameraRun
              ) -> dict[str, float]:
    """Seconds of speech lost while framing and after framing (seated / walker)."""
    times, pan = run.times_s, run.pan_rad
    truth = recording.directions(times)[:, :, 0]
    out = {"speech_s": 0.0, "framing_s": 0.0, "seated_after_s": 0.0, "walker_after_s": 0.0,
           "walker_speech_s": 0.0}
    previous = None
    for turn in turns:
        inside = (times >= turn.start_s) & (times < turn.end_s)
        error = np.abs(np.angle(np.exp(1j * (pan[inside] - truth[turn.talker, inside]))))
        on = error <= _ON_TARGET_RAD
        out["speech_s"] += inside.sum() * _DT_S
        walker = turn.talker >= len(_SEATS)
        if walker:
            out["walker_speech_s"] += inside.sum() * _DT_S
        first = int(np.argmax(on)) if on.any() else on.size
        if turn.talker != previous:
            out["framing_s"] += first * _DT_S
        else:
            first = 0
        key = "walker_after_s" if walker else "seated_after_s"
        out[key] += np.count_nonzero(~on[first:]) * _DT_S
        previous = turn.talker
    return out


def frame_errors(recording: room.Recording, turns: tuple[Turn, ...],
                 frames: tuple[FrameEstimate, ...]) -> dict[str, tuple[float, float]]:
    """Median / p90 error (deg) of short and long windows on speech frames of the active talker."""
    t = np.array([f.t_s for f in frames])
    truth = recording.directions(t)[:, :, 0]
    rows: dict[str, list[float]] = {"short_seated": [], "short_walker": [], "long_seated": [],
                                    "long_walker": []}
    for k, f in enumerate(frames):
        turn = next((u for u in turns if u.start_s + 0.3 <= f.t_s < u.end_s), None)
        if turn is None or not f.speech:
            continue
        who = "walker" if turn.talker >= len(_SEATS) else "seated"
        rows[f"short_{who}"].append(abs(np.angle(np.exp(1j * (f.azimuth_rad
                                                               - truth[turn.talker, k])))))
        if f.fine_azimuth_rad is not None:
            rows[f"long_{who}"].append(abs(np.angle(np.exp(1j * (f.fine_azimuth_rad
                                                                  - truth[turn.talker, k])))))
    return {k: (float(np.rad2deg(np.median(v))), float(np.rad2deg(np.quantile(v, 0.9))))
            for k, v in rows.items() if v}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-5")
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--cache", type=Path, default=None)
    parser.add_argument("--errors", action="store_true", help="also print raw estimate errors")
    args = parser.parse_args()
    settings = MeetingSettings()
    print("seed  on_target_%  frame_s  switches/changes  jitter_deg |  lost % of speech time: "
          "framing  seated  walker(of walker speech)")
    totals = []
    for seed in _seeds(args.seeds):
        t0 = time.perf_counter()
        recording, turns, frames = _frames(seed, args.duration, settings, args.cache)
        run = camera_result(recording, turns, frames, settings, seed)
        r = run.result
        b = breakdown(recording, turns, run)
        sp = b["speech_s"]
        walker_share = 100 * b["walker_after_s"] / max(b["walker_speech_s"], 1e-9)
        print(f"{seed:4d}  {r.on_target_percent:11.1f}  {r.time_to_frame_s:7.2f}  "
              f"{r.switches_per_minute:8.0f}/{r.talker_changes_per_minute:<8.0f}"
              f"{r.pan_jitter_deg:10.2f}  |  {100 * b['framing_s'] / sp:20.1f}"
              f"  {100 * b['seated_after_s'] / sp:6.1f}  {100 * b['walker_after_s'] / sp:6.1f}"
              f"({walker_share:.0f})   [{time.perf_counter() - t0:.1f} s]")
        totals.append((r.on_target_percent, r.time_to_frame_s,
                       r.switches_per_minute - r.talker_changes_per_minute))
        if args.errors:
            for key, (med, p90) in frame_errors(recording, turns, frames).items():
                print(f"      {key:13s} median {med:5.1f}°  p90 {p90:5.1f}°")
    on, frame, extra = (np.array(v) for v in zip(*totals, strict=True))
    print(f"mean  {on.mean():11.1f}  {frame.mean():7.2f}  extra switches/min {extra.mean():+.2f}"
          f"   (min on-target {on.min():.1f})")


if __name__ == "__main__":
    main()
