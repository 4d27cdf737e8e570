"""``tracker camera speed-id``: the speed-table identification on a PTZ camera or its twin.

::

    tracker camera speed-id [--driver visca+udp://HOST:PORT] [--profile NAME] [--axis pan|tilt]
                            [--steps 1,6,12,24 | --count 8] [--rate-hz 25] [--json]

Without ``--driver`` it runs on the emulator's twin of the profile (instant). With one it takes
the camera over in real time (nothing else may steer it meanwhile) and prints each step's
measured rate against the profile's table.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import time
from typing import Any

from tracker.errors import ConfigError, DriverFault


def register(subparsers: Any) -> None:
    """Add ``tracker camera speed-id``."""
    from tracker.cli import command_help
    from tracker.drivers.camera_profiles import DEFAULT_PROFILE, profile_names

    p = subparsers.add_parser("camera", help=command_help("camera"))
    sub = p.add_subparsers(dest="camera_command", metavar="JOB", required=True)
    s = sub.add_parser(
        "speed-id",
        help="measure the speed table per direction and set it against the profile's",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    s.add_argument(
        "--driver",
        default=None,
        metavar="URL",
        help="visca+udp://HOST:PORT or visca+tcp://... (default: the profile's twin, simulated)",
    )
    s.add_argument("--profile", default=DEFAULT_PROFILE, choices=profile_names(), help="camera profile")
    s.add_argument("--axis", default="pan", choices=("pan", "tilt"))
    s.add_argument(
        "--steps",
        default=None,
        help="speed steps to measure, comma-separated (default: --count spread over the table)",
    )
    s.add_argument("--count", type=int, default=8, help="how many steps to spread over the table (default 8)")
    s.add_argument(
        "--rate-hz", type=float, default=25.0, help="command/inquiry rate with --driver (default 25)"
    )
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(func=run_speed_id)


def _steps(text: str | None) -> tuple[int, ...] | None:
    if not text:
        return None
    try:
        return tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise ConfigError(f"--steps {text!r}: expected whole numbers, e.g. 1,6,12,24") from None


async def _on_camera(args: argparse.Namespace) -> Any:  # noqa: ANN401 - a SpeedIdResult
    from tracker.drivers.camera_profiles import get_profile
    from tracker.drivers.spec import parse_driver_url
    from tracker.drivers.visca import ViscaCamera
    from tracker.workbench.camera.speed_id import ViscaRig, identify_speed_table

    spec = parse_driver_url(args.driver)
    if spec.kind != "visca":
        raise ConfigError(f"--driver {args.driver!r}: speed-id needs a camera (visca+udp:// or visca+tcp://)")
    cam = ViscaCamera(spec, get_profile(args.profile), rate_hz=args.rate_hz)
    cam.start()
    try:
        end = time.monotonic() + 5.0
        while not cam.ready:
            if time.monotonic() > end:
                raise DriverFault(
                    f"camera {args.driver} did not answer within 5 s ({cam.describe()['last_error']})"
                )
            await asyncio.sleep(0.02)
        cam.enable()
        return await identify_speed_table(
            ViscaRig(cam), args.axis, steps=_steps(args.steps), count=args.count
        )
    finally:
        cam.disable()
        await cam.close()


def format_speed_id(res: Any) -> str:  # noqa: ANN401 - a SpeedIdResult
    """The measured table as a person reads it (degrees)."""
    lines = [
        f"speed-table identification, {res.axis} axis, against the {res.profile} profile "
        f"({len(res.runs)} runs, {res.elapsed_s:.1f} s)",
        "",
        f"{'step':>4} {'dir':>3} {'measured °/s':>13} {'± °/s':>7} {'profile °/s':>12} {'departure':>10}",
    ]
    for r in res.runs:
        lines.append(
            f"{r.step:4d} {'+' if r.direction > 0 else '-':>3} {math.degrees(r.rate_rad_s):13.3f} "
            f"{math.degrees(r.stderr_rad_s):7.3f} {math.degrees(r.profile_rad_s):12.3f} "
            f"{r.deviation_percent:+9.1f} %"
        )
    return "\n".join([*lines, "", *res.notes])


def run_speed_id(args: argparse.Namespace) -> int:
    """``tracker camera speed-id``."""
    from tracker.drivers.camera_profiles import get_profile
    from tracker.drivers.camera_twin import CameraTwin
    from tracker.workbench.camera.speed_id import TwinRig, identify_speed_table

    if args.driver:
        res = asyncio.run(_on_camera(args))
    else:
        rig = TwinRig(CameraTwin(get_profile(args.profile)), period_s=1.0 / args.rate_hz)
        res = asyncio.run(identify_speed_table(rig, args.axis, steps=_steps(args.steps), count=args.count))
    print(json.dumps(res.to_dict()) if args.json else format_speed_id(res))
    return 0
