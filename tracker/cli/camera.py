"""``tracker camera-emulator``: a PTZ camera speaking VISCA over IP on 127.0.0.1 (the twin)."""

from __future__ import annotations

import argparse
import asyncio
import math
from typing import Any

from tracker.errors import ConfigError


def register(subparsers: Any) -> None:
    """Add ``camera-emulator`` to the ``tracker`` command."""
    from tracker.cli import command_help
    from tracker.drivers.camera_profiles import DEFAULT_PROFILE, profile_names

    p = subparsers.add_parser(
        "camera-emulator",
        help=command_help("camera-emulator"),
        description="A VISCA camera backed by a twin of a PTZ head (speed table, acceleration, "
        "backlash, position counts, zoom, presets), with packet loss and latency injection. Point "
        "the console at it with driver = \"visca+udp://127.0.0.1:PORT\".",
    )
    p.add_argument("--port", type=int, default=52381, help="port to listen on (0 picks a free one)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default: loopback only)")
    p.add_argument("--profile", default=DEFAULT_PROFILE, choices=profile_names(), help="camera profile")
    p.add_argument("--tcp", action="store_true", help="raw VISCA over TCP instead of VISCA over IP on UDP")
    p.add_argument("--loss", type=float, default=0.0, help="drop each datagram with this probability (0-1)")
    p.add_argument("--latency-ms", type=float, default=0.0, help="added round-trip latency (ms)")
    p.add_argument("--no-limits", action="store_true",
                   help="answer Pan-tiltLimitSet/LimitClear with a syntax error (a camera without them)")
    p.add_argument("--seed", type=int, default=None, help="seed of the loss draws")
    p.add_argument("--duration-s", type=float, default=None, help="stop after this long (default: Ctrl-C)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Serve until interrupted (or ``--duration-s``); print a status line every second."""
    if not 0 <= args.port < 65536:
        raise ConfigError(f"--port {args.port} is outside 0..65535")
    asyncio.run(_serve(args))
    return 0


async def _serve(args: argparse.Namespace) -> None:
    from tracker.drivers.camera_emulator import CameraEmulator

    emulator = CameraEmulator(
        args.profile, host=args.host, port=args.port, transport="tcp" if args.tcp else "udp",
        loss=args.loss, latency_s=args.latency_ms / 1e3, seed=args.seed,
        limit_commands=not args.no_limits)
    port = await emulator.start()
    scheme = "visca+tcp" if args.tcp else "visca+udp"
    print(f"camera emulator ({args.profile}) on {scheme}://{args.host}:{port} "
          f"loss {args.loss:g}, latency {args.latency_ms:g} ms"
          f"{', Pan-tiltLimitSet refused' if args.no_limits else ''}; Ctrl-C to stop", flush=True)
    loop = asyncio.get_running_loop()
    end = None if args.duration_s is None else loop.time() + args.duration_s
    try:
        while end is None or loop.time() < end:
            await asyncio.sleep(1.0 if end is None else max(0.0, min(1.0, end - loop.time())))
            pan, tilt = (emulator.twin.axes[a].motor_rad for a in ("pan", "tilt"))
            lims = [emulator.twin.axes[a].bounds() for a in ("pan", "tilt")]
            s, r = emulator.stats, emulator.responder_stats
            print(f"pan {math.degrees(pan):7.2f}°  tilt {math.degrees(tilt):6.2f}°  "
                  f"zoom {emulator.twin.zoom_counts():5d}  rx {s.received}  tx {s.sent}  "
                  f"lost {s.dropped_in}+{s.dropped_out}  moves {r.motion_commands}  "
                  f"range pan {math.degrees(lims[0][0]):.1f}..{math.degrees(lims[0][1]):.1f}° "
                  f"tilt {math.degrees(lims[1][0]):.1f}..{math.degrees(lims[1][1]):.1f}°", flush=True)
    finally:
        await emulator.close()
