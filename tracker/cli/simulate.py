"""``tracker simulate``: the scripted pointing test on the twin (default) or the meeting scenario."""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import sys
from typing import Any

from tracker.errors import ConfigError


def register(subparsers: Any) -> None:
    """Add ``simulate`` to the ``tracker`` command."""
    from tracker.cli import command_help

    p = subparsers.add_parser(
        "simulate",
        help=command_help("simulate"),
        description="Scripted pointing test on the twin: per-axis margins, step and sine figures.",
    )
    p.add_argument(
        "scenario",
        nargs="?",
        default="pointing",
        choices=("pointing", "meeting"),
        help="pointing: steps, ramps, 1 Hz sine per axis (default); meeting: the audio-steered meeting",
    )
    p.add_argument("--axis", choices=("pan", "tilt"), help="one axis only (default: both)")
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds (pointing: the 20 s script repeats; meeting: default 60)",
    )
    p.add_argument(
        "--effects", default="", metavar="A,B", help="hidden effects added to the twin (catalogue defaults)"
    )
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="EFFECT.PARAM=VALUE",
        help="set a hidden effect's parameter (SI units), e.g. gravity.torque=0.03; repeatable",
    )
    p.add_argument(
        "--rig-config", default=None, metavar="FILE.json", help="hidden effects per axis (rig config file)"
    )
    p.add_argument(
        "--controller",
        default=None,
        metavar="NAME",
        help="seed_lead: the seed's reproduced lead; observer_pd_ff: ours (default); checked "
        "when the run starts (listing the registry imports python-control)",
    )
    p.add_argument(
        "--record", default=None, metavar="FILE.csv", help="write the run as a t,u,theta log (one per axis)"
    )
    p.add_argument("--seed", type=int, default=0, help="meeting: random seed")
    p.add_argument("--tracker", default=None, choices=("map", "kalman"),
                   help="meeting: the talker tracker (default map; kalman for comparison)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the chosen scenario; print figures."""
    if args.scenario == "meeting":
        return _run_meeting(args)
    from tracker.control.design import CONTROLLERS, DEFAULT_CONTROLLER
    from tracker.control.pointing import SCRIPT_S
    from tracker.control.scorecard import run_pointing, twin_for
    from tracker.drivers.sim import load_rig_config
    from tracker.recording import write_measurements

    controller = args.controller or DEFAULT_CONTROLLER
    if controller not in CONTROLLERS:
        raise ConfigError(f"--controller {controller!r}: choose one of {', '.join(sorted(CONTROLLERS))}")
    effects = [e.strip() for e in args.effects.split(",") if e.strip()]
    params = _parse_params(args.param)
    for name in params:
        effect = name.split(".")[0]
        if effect not in effects and effect not in ("inertia", "viscous", "coulomb", "quantization"):
            effects.append(effect)
    if args.rig_config and (effects or params):
        raise ConfigError("give hidden effects either with --rig-config or with --effects/--param, not both")
    rig = load_rig_config(args.rig_config) if args.rig_config else None
    axes = [args.axis] if args.axis else ["pan", "tilt"]
    duration = SCRIPT_S if args.duration is None else args.duration
    out: dict[str, Any] = {}
    logs = {}
    for axis in axes:
        twin = twin_for(axis, effects, rig, params)
        res = run_pointing(axis, duration, controller, twin, record=bool(args.record))
        out[axis] = res.figures
        if res.measurement is not None:
            logs[axis] = res.measurement
    if args.record:
        for path in write_measurements(logs, args.record):
            print(f"recorded {path}", file=sys.stderr)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for axis, fig in out.items():
            print(f"{axis}:")
            for k, v in fig.items():
                print(f"  {k:40s} {v}")
    return 0


def _parse_params(items: list[str]) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"--param {item!r}: expected EFFECT.PARAM=NUMBER") from None
        if not sep:
            raise ConfigError(f"--param {item!r}: expected EFFECT.PARAM=NUMBER")
    return out


def _run_meeting(args: argparse.Namespace) -> int:
    try:
        meeting = importlib.import_module("tracker.scenarios.meeting")
    except ModuleNotFoundError as exc:
        raise ConfigError(f"the meeting scenario is not available ({exc.name} is missing)") from None
    duration = 60.0 if args.duration is None else args.duration
    settings = meeting.MeetingSettings()
    if args.tracker is not None:
        settings = dataclasses.replace(settings, tracker=args.tracker)
    result = meeting.run_meeting(seed=args.seed, duration_s=duration, settings=settings)
    figures = result.to_dict() if hasattr(result, "to_dict") else result
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        for k, v in figures.items():
            print(f"{k:32s} {v}")
    return 0
