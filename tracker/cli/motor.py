"""``tracker motor-emulator``: a DC rig's motor controller board on a pseudo-terminal (the twin)."""

from __future__ import annotations

import argparse
import gc
import math
import time
from typing import Any


def register(subparsers: Any) -> None:
    """Add ``motor-emulator`` to the ``tracker`` command."""
    from tracker.cli import command_help
    from tracker.drivers.motor_board import SEED_COUNTS_PER_REV, SEED_GEAR_RATIO

    p = subparsers.add_parser(
        "motor-emulator",
        help=command_help("motor-emulator"),
        description="A motor controller board (docs/serial-protocol.md) backed by the rig's twin (the "
        "pan and tilt presets, optional hidden effects), on a pty. Prints the device to open; point "
        "the console at it with driver = \"serial://DEVICE?baud=1000000\".",
    )
    p.add_argument("--pty-link", metavar="PATH", default=None,
                   help="also make PATH (e.g. /tmp/ttyRIG) a symlink to the device; a restarted "
                        "emulator keeps the name")
    p.add_argument("--rig-config", metavar="RIG.json", default=None,
                   help="hidden effects of the twin (the simulated rig's config format)")
    p.add_argument("--cpr", type=int, default=SEED_COUNTS_PER_REV,
                   help=f"encoder counts per motor revolution (default {SEED_COUNTS_PER_REV})")
    p.add_argument("--gear-ratio", type=float, default=SEED_GEAR_RATIO,
                   help=f"motor revolutions per load revolution (default {SEED_GEAR_RATIO:g})")
    p.add_argument("--duration-s", type=float, default=None, help="stop after this long (default: Ctrl-C)")
    p.add_argument("--quiet", action="store_true", help="no status line every second")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Serve until interrupted (or ``--duration-s``); print a status line every second."""
    from tracker.drivers.motor_board import MotorBoard, RigTwin
    from tracker.drivers.motor_emulator import MotorEmulator
    from tracker.drivers.sim import load_rig_config

    twin = RigTwin(load_rig_config(args.rig_config) if args.rig_config else None)
    board = MotorBoard(twin, counts_per_rev=args.cpr, gear_ratio=args.gear_ratio)
    emulator = MotorEmulator(board, pty_link=args.pty_link)
    # What the imports left (numba, the twin: ~100 000 objects) out of the collector's sight: a
    # full collection over them while serving held the answers up 60 ms on a loaded machine,
    # which a board never does (the service does the same, app/service.py).
    gc.collect()
    gc.freeze()
    path = emulator.start()
    print(f"motor controller emulator on {path}"
          + (f" (-> {emulator.device})" if args.pty_link else "")
          + f"; driver = \"serial://{path}?baud=1000000\"; Ctrl-C to stop", flush=True)
    end = None if args.duration_s is None else time.monotonic() + args.duration_s
    try:
        while end is None or time.monotonic() < end:
            time.sleep(1.0 if end is None else max(0.0, min(1.0, end - time.monotonic())))
            if args.quiet:
                continue
            board.catch_up()
            pan, tilt = (math.degrees(twin.load_rad(a)) for a in ("pan", "tilt"))
            print(f"pan {pan:7.2f}°  tilt {tilt:6.2f}°  {'armed' if board.armed else 'disarmed'}  "
                  f"command {board.command_mv['pan']:+6d} {board.command_mv['tilt']:+6d} mV  "
                  f"lines {board.lines}  errors {board.errors}  watchdog trips {board.watchdog_trips}",
                  flush=True)
    finally:
        emulator.close()
    return 0
