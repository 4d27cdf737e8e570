"""``tracker serve``: the service on the simulated rig (the web console when ``app`` is installed)."""

from __future__ import annotations

import argparse
import asyncio
import importlib
import math
from typing import Any


def register(subparsers: Any) -> None:
    """Add ``serve`` to the ``tracker`` command."""
    from tracker.cli import command_help

    p = subparsers.add_parser("serve", help=command_help("serve"))
    p.add_argument("--host", default=None, help="listen address (console)")
    p.add_argument("--port", type=int, default=None, help="listen port (console)")
    p.add_argument("--config", default=None, metavar="FILE", help="service settings file")
    p.add_argument(
        "--rig-config", default=None, metavar="FILE.json", help="hidden effects of the simulated rig (JSON)"
    )
    p.add_argument("--engine-only", action="store_true", help="run the engine without the web console")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Start the console if ``app.main.run_server`` exists, else the engine alone (status per second)."""
    if not args.engine_only:
        try:
            app_main = importlib.import_module("app.main")
        except ModuleNotFoundError as exc:
            if not (exc.name or "").startswith("app"):
                raise
            app_main = None
        if app_main is not None and hasattr(app_main, "run_server"):
            app_main.run_server(
                host=args.host, port=args.port, config=args.config, rig_config=args.rig_config
            )
            return 0
    asyncio.run(_engine_only(args.rig_config))
    return 0


async def _engine_only(rig_config: str | None) -> None:
    from tracker.drivers.sim import SimDriver
    from tracker.engine import Engine

    driver = SimDriver.from_config(rig_config) if rig_config else SimDriver()
    engine = Engine(driver)
    task = asyncio.create_task(engine.run(realtime=True))
    print("3DAT engine on the simulated rig (no console); Ctrl-C to stop", flush=True)
    try:
        while not task.done():
            await asyncio.sleep(1.0)
            s = engine.status()
            print(
                f"t={s.t_s:8.1f} s  mode={s.mode:8s}  pan={math.degrees(s.pan_rad):7.2f}°  "
                f"tilt={math.degrees(s.tilt_rad):7.2f}°  faults={len(s.faults)}",
                flush=True,
            )
    finally:
        engine.stop()
        await task
