"""Head-mounted array: base-frame accuracy with the head still, and which head angle to use while it turns.

Prints (1) the speech-window azimuth error in the base frame for arrays carried on the head at
fixed pan/tilt, and (2) for a head panning steadily under a talker, the error when each window
is turned with the head's angle at the window's end, at its centre, the uniform mean over the
window, and the power-weighted mean (what tracker.audio.head does).

    .venv/bin/python bench/bench_head_mounted.py [--rate-deg-s 20]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

from tracker.audio import room
from tracker.audio.array import load_array, rotation_world_head
from tracker.audio.head import HeadPoses, direction_to_base, frames_to_base, locate_head_mounted
from tracker.audio.head_room import simulate_head_mounted
from tracker.audio.pipeline import Pipeline, WindowSettings
from tracker.audio.speech import synthetic_speech

ARRAYS = "examples/arrays/{}.json"
ROOM = room.RoomSettings(rt60_s=0.4, snr_db=10.0, ism_order=10)
FS = 16000


def err_deg(a: float, b: float) -> float:
    return abs(math.degrees(math.remainder(a - b, 2 * math.pi)))


def still_heads() -> None:
    print("1. head still; RT60 0.4 s, SNR 10 dB, talker 2 m, 0.5 s windows, srp_phat")
    print(f"{'array':14s} {'pan':>5s} {'tilt':>5s} {'talker':>7s} {'median':>7s} {'p90':>6s} "
          f"{'el med err':>10s}  n")
    cases = [("square4_65mm", 50, 0, 10, 1.2), ("square4_65mm", -60, 20, -20, 1.2),
             ("circular6_46mm", 70, 10, 0, 1.2), ("cube8_50mm", -35, 15, 10, 1.7),
             ("seed_pairs", 30, 10, 45, 1.5)]
    placement = room.centre_placement(ROOM)
    for k, (name, pan_deg, tilt_deg, az_deg, mouth_m) in enumerate(cases):
        array = dataclasses.replace(load_array(ARRAYS.format(name)), mount="head")
        speech = synthetic_speech(4.0, FS, seed=10 + k)
        pos = room.position_from_direction(placement, math.radians(az_deg), 2.0, mouth_m)
        pan, tilt = math.radians(pan_deg), math.radians(tilt_deg)
        rec = simulate_head_mounted(ROOM, array, placement.position_m,
                                    [room.static_talker(speech.samples, speech.active, pos)],
                                    np.zeros(1), np.array([pan]), np.array([tilt]), seed=k)
        true_az, true_el = rec.directions(np.array([1.0]))[0, 0]
        poses = HeadPoses.from_arrays(np.zeros(1), np.array([pan]), np.array([tilt]))
        res = locate_head_mounted(Pipeline(array, FS, "srp_phat", WindowSettings(0.5, 0.1, 1.5)),
                                  rec.audio, poses)
        frames = [f for f in res.frames if f.speech]
        errors = [err_deg(f.azimuth_rad, true_az) for f in frames]
        el = [abs(math.degrees(f.elevation_rad - true_el)) for f in frames if f.elevation_rad is not None]
        el_text = f"{np.median(el):10.1f}" if el else f"{'-':>10s}"
        print(f"{name:14s} {pan_deg:5.0f} {tilt_deg:5.0f} {az_deg:7.0f} {np.median(errors):7.1f} "
              f"{np.percentile(errors, 90):6.1f} {el_text}  {len(frames)}")


def turning_head(rate_deg_s: float) -> None:
    duration_s = 80.0 / rate_deg_s
    print(f"\n2. head pans steadily -40° -> +40° at {rate_deg_s:.0f}°/s ({duration_s:.1f} s) under a "
          "talker at 10°; 4-mic square, 0.3 s windows")
    array = dataclasses.replace(load_array(ARRAYS.format("square4_65mm")), mount="head")
    placement = room.centre_placement(ROOM)
    speech = synthetic_speech(duration_s, FS, seed=3)
    pos = room.position_from_direction(placement, math.radians(10.0), 2.0)
    head_t = np.array([0.0, duration_s])
    head_pan = np.radians([-40.0, 40.0])
    t0 = time.perf_counter()
    rec = simulate_head_mounted(ROOM, array, placement.position_m,
                                [room.static_talker(speech.samples, speech.active, pos)],
                                head_t, head_pan, np.zeros(2))
    sim_s = time.perf_counter() - t0
    true_az = rec.directions(np.array([1.0]))[0, 0, 0]
    pipeline = Pipeline(array, FS, "srp_phat", WindowSettings(0.3, 0.1, None))
    poses = HeadPoses.from_arrays(head_t, head_pan, np.zeros(2))
    head_frames = [f for f in pipeline.estimate_frames(rec.audio) if f.speech]

    def with_angle_at(fraction: float) -> list[float]:
        out = []
        for f in head_frames:
            t = f.end_s - (1.0 - fraction) * pipeline.windows.window_s
            pan = float(np.interp(t, head_t, head_pan))
            out.append(direction_to_base(f.azimuth_rad, None, rotation_world_head(pan, 0.0))[0])
        return out

    uniform = []
    for f in head_frames:
        motion = poses.motion_over(f.end_s - pipeline.windows.window_s, f.end_s)
        uniform.append(direction_to_base(f.azimuth_rad, None, motion.r_world_head)[0])
    weighted = [f.azimuth_rad for f in frames_to_base(tuple(head_frames), rec.audio, pipeline, poses)]
    print(f"{'head angle used':28s} {'median':>7s} {'p90':>6s} {'mean signed':>12s}")
    for label, values in (("window end", with_angle_at(1.0)), ("window centre", with_angle_at(0.5)),
                          ("uniform mean over window", uniform),
                          ("power-weighted mean", weighted)):
        signed = [math.degrees(math.remainder(v - true_az, 2 * math.pi)) for v in values]
        errors = np.abs(signed)
        print(f"{label:28s} {np.median(errors):7.2f} {np.percentile(errors, 90):6.2f} "
              f"{np.mean(signed):12.2f}")
    print(f"({len(head_frames)} speech windows; room simulation {sim_s:.1f} s)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate-deg-s", type=float, default=20.0)
    args = parser.parse_args()
    still_heads()
    turning_head(args.rate_deg_s)


if __name__ == "__main__":
    main()
