"""The ``tracker`` command: builds the argument parser from one module per command group.

Each command module exposes ``register(subparsers)`` which adds its sub-command(s) and sets
``func`` on the parsed namespace; ``func(args) -> int`` is the exit code. Engine errors
(:class:`tracker.errors.TrackerError`) become a one-line ``error: ...`` and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

# One BLAS thread: the fits are many small solves, where threads only fight over the cores
# (halves fit time on a 2-core machine). Set before numpy loads; an explicit setting wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from tracker.errors import TrackerError  # noqa: E402

# The commands, in the order they appear in --help: the module that registers each and its
# one-line help. Only the module of the command given is imported (the others pull in scipy,
# python-control, numba, pyroomacoustics: seconds of start-up); ``tracker --help`` imports none.
COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("tracker.cli.simulate",
                 "run the pointing test (steps, ramps, 1 Hz sine) on the digital twin, or a meeting"),
    "serve": ("tracker.cli.serve", "run the service (web console on the simulated rig)"),
    "model": ("tracker.cli.model", "model workbench: compare, fit, diagnose"),
    "friction-id": ("tracker.cli.friction",
                    "identify viscous and Coulomb friction per direction (seed §3.1)"),
    "audio": ("tracker.cli.audio", "locate talkers in multichannel audio"),
    "camera-emulator": ("tracker.cli.camera", "emulate a PTZ camera (VISCA over IP on UDP, or raw "
                        "VISCA on TCP) on 127.0.0.1"),
    "camera": ("tracker.cli.camera_jobs", "PTZ camera jobs: speed-table identification (speed-id)"),
    "motor-emulator": ("tracker.cli.motor",
                       "emulate the DC rig's serial motor controller on a pseudo-terminal"),
    "warm-up": ("tracker.cli.warm", "compile the twin and the workbench into numba's cache (once "
                "after an install: the first diagnosis is otherwise ~1.5 min slower)"),
}
COMMAND_MODULES = tuple(module for module, _ in COMMANDS.values())
COMMAND_OWNERS = {name: module for name, (module, _) in COMMANDS.items()}


def command_help(command: str) -> str:
    """The one-line help of ``command`` (shown by ``tracker --help``)."""
    return COMMANDS[command][1]


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """Return the ``tracker`` argument parser.

    With a known ``command`` only its module is imported and registers its full options; with
    none (``tracker --help``, a typo) every command is listed by name and help only.
    """
    parser = argparse.ArgumentParser(
        prog="tracker",
        description="3DAT: audio-steered pan/tilt camera engine, digital twin and model workbench.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    if command in COMMANDS:
        module_name = COMMAND_OWNERS[command]
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:  # work in progress: list the command, run nothing
            if exc.name != module_name:
                raise
        else:
            module.register(subparsers)
            return parser
    for name, (_, text) in COMMANDS.items():
        subparsers.add_parser(name, help=text)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``tracker`` console script."""
    args_list = list(sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser(args_list[0] if args_list else None)
    except TrackerError as exc:  # e.g. an effect plug-in in TRACKER_EFFECTS that fails to load
        print(f"error: {exc}", file=sys.stderr)
        return 2
    args = parser.parse_args(args_list)
    if not hasattr(args, "func"):
        parser.print_help()
        return 1
    try:
        return int(args.func(args) or 0)
    except TrackerError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
