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

# Command modules, in the order they appear in --help. A module that is missing (work in
# progress) is skipped so the rest of the command line keeps working.
COMMAND_MODULES = (
    "tracker.cli.simulate",
    "tracker.cli.serve",
    "tracker.cli.model",
    "tracker.cli.friction",
    "tracker.cli.audio",
    "tracker.cli.camera",
    "tracker.cli.motor",
)
# The first word of the command line -> the one module that registers it. Only that module is
# imported (the others pull in scipy, python-control, pyroomacoustics: seconds of start-up).
COMMAND_OWNERS = {
    "simulate": "tracker.cli.simulate",
    "serve": "tracker.cli.serve",
    "model": "tracker.cli.model",
    "friction-id": "tracker.cli.friction",
    "audio": "tracker.cli.audio",
    "camera-emulator": "tracker.cli.camera",
    "motor-emulator": "tracker.cli.motor",
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """Return the ``tracker`` argument parser; with ``command`` only that command is registered."""
    parser = argparse.ArgumentParser(
        prog="tracker",
        description="3DAT: audio-steered pan/tilt camera engine, digital twin and model workbench.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    owner = COMMAND_OWNERS.get(command or "")
    for module_name in (owner,) if owner else COMMAND_MODULES:
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                continue
            raise
        module.register(subparsers)
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
