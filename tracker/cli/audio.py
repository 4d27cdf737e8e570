"""The ``tracker audio`` command group: ``locate`` a talker in a multichannel recording."""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING

import numpy as np

from tracker.audio.array import load_array
from tracker.audio.localizers import DEFAULT_LOCALIZER, LOCALIZERS
from tracker.audio.trackers import TRACKERS, choose_tracker
from tracker.errors import ConfigError

if TYPE_CHECKING:  # the pipeline (scipy, numba) is imported when a recording is located
    from tracker.audio.pipeline import LocateResult


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add ``audio locate`` to the ``tracker`` parser."""
    from tracker.cli import command_help

    audio = subparsers.add_parser("audio", help=command_help("audio"))
    commands = audio.add_subparsers(dest="audio_command", metavar="SUBCOMMAND")
    locate = commands.add_parser(
        "locate",
        help="per-window direction estimates and the tracked camera direction of a WAV file",
    )
    locate.add_argument("recording", metavar="REC.wav", help="multichannel WAV, one channel per mic")
    locate.add_argument("--array", required=True, metavar="ARRAY.json",
                        help='mic geometry {"mics": [[x, y, z], ...] (metres), "mount": '
                             '"room"|"wall"|"table"|"ceiling"|"head", "field_of_view": '
                             '{"azimuth_deg": [lo, hi], "elevation_deg": [lo, hi]}}')
    locate.add_argument("--encoder", metavar="LOG.csv", default=None,
                        help="head angles during the recording, for a head-mounted array: CSV "
                             "t (s from the first sample), pan, tilt (rad; or pan_deg, tilt_deg), "
                             "or RUN.csv for the RUN_pan.csv/RUN_tilt.csv logs of --record")
    locate.add_argument("--method", default=DEFAULT_LOCALIZER, choices=sorted(LOCALIZERS),
                        help=f"localizer (default {DEFAULT_LOCALIZER})")
    locate.add_argument("--window-s", type=float, default=0.5, help="analysis window (s)")
    locate.add_argument("--hop-s", type=float, default=0.1, help="window hop (s)")
    locate.add_argument("--fine-window-s", type=float, default=1.5,
                        help="longer window that refines the tracked talker (s); 0 turns it off")
    locate.add_argument("--front-only", action="store_true",
                        help="narrow the array's field of view to -90°..90° azimuth (an array on "
                             "a wall or under a camera; an array file can say so itself: "
                             '"mount": "wall"); for a head-mounted array, of the base frame')
    locate.add_argument("--tracker", default="auto", choices=("auto", *TRACKERS),
                        help="talker tracker: map (steered-response maps; srp_phat) or kalman "
                             "(window peaks); auto picks map where it applies")
    locate.add_argument("--json", action="store_true", help="print the JSON contract")
    locate.set_defaults(func=run_locate)
    audio.set_defaults(func=lambda args: _help(audio))


def _help(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 1


def run_locate(args: argparse.Namespace) -> int:
    """``tracker audio locate``: print the JSON contract or a readable summary.

    Directions are in the base frame: a head-mounted array's estimates are turned with the
    head's angles from ``--encoder`` (required for such an array, refused for a room one).
    """
    from tracker.audio.head import check_coverage, locate_head_mounted, read_encoder_log
    from tracker.audio.pipeline import Pipeline, WindowSettings
    from tracker.audio.sources import read_wav

    array = load_array(args.array)
    fs_hz, audio = read_wav(args.recording)
    # Where talkers can be (base frame): the array's field of view, narrowed by --front-only.
    view = array.field_of_view.narrowed((-np.pi / 2, np.pi / 2), array.name) if args.front_only \
        else array.field_of_view
    searched = view.azimuth_range_rad
    options = ({"azimuth_range_rad": searched}
               if searched is not None and args.method in ("srp_phat", "srp_dpd")
               and not array.head_mounted else {})
    fine_s = args.fine_window_s if args.fine_window_s and args.fine_window_s > 0 else None
    tracker = choose_tracker(args.method) if args.tracker == "auto" else args.tracker
    pipeline = Pipeline(array, fs_hz, args.method,
                        WindowSettings(args.window_s, args.hop_s, fine_s),
                        localizer_options=options, tracker=tracker,
                        base_azimuth_range_rad=searched if array.head_mounted else None)
    if array.head_mounted:
        if args.encoder is None:
            raise ConfigError(f"{array.name} is head-mounted (\"mount\": \"head\"): give the "
                              "head's angles during the recording with --encoder LOG.csv "
                              "(columns t, pan, tilt; one row if the head did not move)")
        poses = read_encoder_log(args.encoder)
        check_coverage(poses, audio.shape[1] / fs_hz, 0.25, str(args.encoder))
        result = locate_head_mounted(pipeline, audio, poses)
    elif args.encoder is not None:
        raise ConfigError(f"--encoder applies to head-mounted arrays; {array.name} is "
                          'room-mounted (add "mount": "head" if it rides on the pan/tilt head)')
    else:
        result = pipeline.run(audio)
    if args.json:
        json.dump(result.to_dict(), sys.stdout)
        sys.stdout.write("\n")
    else:
        sys.stdout.write(summary(result, args.recording))
    return 0


def summary(result: LocateResult, name: str) -> str:
    """A few human-readable lines about a locate result."""
    frames = result.frames
    speech = [f for f in frames if f.speech]
    lines = [
        f"{name}: {len(frames)} windows at {result.fs_hz} Hz with {result.method}, "
        f"{len(speech)} with speech",
    ]
    if speech:
        speech_deg = np.rad2deg([f.azimuth_rad for f in speech])
        lines.append(f"speech azimuth: median {np.median(speech_deg):.1f}°, range "
                     f"{speech_deg.min():.1f}° to {speech_deg.max():.1f}°")
    last_az: float | None = None
    for point in result.track:
        if point.shot == "none":
            continue
        az = float(np.rad2deg(point.azimuth_rad))
        if last_az is None or abs(az - last_az) >= 5.0:
            lines.append(f"  t={point.t_s:6.2f} s  camera -> {az:6.1f}° ({point.shot})")
            last_az = az
    if last_az is None:
        lines.append("no talker found")
    return "\n".join(lines) + "\n"
