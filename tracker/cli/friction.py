"""``tracker friction-id``: the seed's friction-identification experiment on the simulated rig.

::

    tracker friction-id --axis pan|tilt [--json]
                        [--hidden-effects RIG.json | --effects a,b --set NAME=VALUE ...
                         | --driver serial:///dev/ttyUSB0?baud=1000000 [--gear-ratio R]]

``RIG.json`` is the simulated rig's config (see :mod:`tracker.drivers.sim`); ``--effects`` and
``--set`` give the rig hidden effects on the chosen axis instead; ``--driver`` runs it on a
real DC rig behind its motor controller board (or ``tracker motor-emulator``), in real time.
Prints per-direction viscous and Coulomb friction, the break-away torques and (with
``--json``) the torque-vs-velocity points.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

from tracker.errors import ConfigError

if TYPE_CHECKING:  # the engine is imported when the command runs, not for --help
    from tracker.drivers.motor import MotorDriver
    from tracker.drivers.sim import SimDriver
    from tracker.workbench.experiments.friction_id import FrictionResult


def _rig(args: argparse.Namespace) -> SimDriver:
    from tracker.drivers.sim import SimDriver, load_rig_config, rig_models
    from tracker.plant.effects import get_param

    if args.hidden_effects and (args.effects or args.set):
        raise ConfigError("give either --hidden-effects RIG.json or --effects/--set, not both")
    if args.hidden_effects:
        return SimDriver(load_rig_config(args.hidden_effects))
    effects = [e.strip() for e in (args.effects or "").split(",") if e.strip()]
    params: dict[str, float] = {}
    for item in args.set or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"--set {item!r}: expected NAME=VALUE, e.g. coulomb_asymmetry.negative=0.07")
        try:
            v = float(value)
        except ValueError:
            raise ConfigError(f"--set {item!r}: {value!r} is not a number") from None
        params[name.strip()] = get_param(name.strip()).check(v, f"--set {name.strip()}")
    return SimDriver(rig_models({args.axis: {"effects": effects, "params": params}}))


def format_result(res: FrictionResult) -> str:
    """The identification as a person reads it."""
    lines = [
        f"friction identification, {res.axis} axis (K = {res.gain_nm_per_v:.5g} N·m/V, "
        f"{len(res.points)} runs, {res.simulated_s:.1f} s of rig time)",
        "",
    ]
    lines.append(
        f"{'direction':<10} {'viscous N·m·s/rad':>20} {'Coulomb N·m':>14} {'break-away N·m':>15} {'runs':>5}"
    )
    for name, line, brk in (
        ("positive", res.positive, res.breakaway_positive_nm),
        ("negative", res.negative, res.breakaway_negative_nm),
    ):
        lines.append(
            f"{name:<10} {line.viscous_nm_s_per_rad:12.4g} ± {line.viscous_se:<7.2g}"
            f"{line.coulomb_nm:8.4g} ± {line.coulomb_se:<5.2g}{brk:13.4g} {line.points:5d}"
        )
    ep, en = res.stiction_excess_nm()
    if res.shows_stiction():
        lines.append(
            f"stiction: break-away needs {1e3 * ep:.1f} / {1e3 * en:.1f} mN·m more than Coulomb "
            "(positive / negative): add the stiction effect"
        )
    else:
        lines.append(f"no stiction: break-away is within {1e3 * max(abs(ep), abs(en)):.1f} mN·m of Coulomb")
    lines += ["", "torque vs velocity (runs that reached a steady measurement):"]
    for p in res.points:
        if p.moved:
            lines.append(f"  {p.volts:+8.4f} V  {p.velocity_rad_s:+8.3f} rad/s  {p.torque_nm:+.5f} N·m")
    return "\n".join(lines)


def _serial_rig(args: argparse.Namespace) -> MotorDriver:
    from tracker.drivers.serial_motor import SerialMotorDriver
    from tracker.drivers.spec import parse_driver_url

    if args.hidden_effects or args.effects or args.set:
        raise ConfigError("--driver runs on a real rig: --hidden-effects, --effects and --set do not apply")
    spec = parse_driver_url(args.driver)
    if spec.kind != "serial":
        raise ConfigError(f"--driver {args.driver!r}: friction-ID needs a voltage-driven rig (serial://...)")
    driver = SerialMotorDriver(spec, {args.axis: args.gear_ratio} if args.gear_ratio else None)
    driver.start()
    driver.wait_ready(5.0)
    return driver


def run(args: argparse.Namespace) -> int:
    """``tracker friction-id``."""
    from tracker.workbench.experiments.friction_id import run_friction_id

    driver = _serial_rig(args) if args.driver else _rig(args)
    try:
        res = run_friction_id(driver, args.axis, voltages_per_direction=args.voltages)
    finally:
        close = getattr(driver, "close", None)
        if close is not None:
            close()
    if args.json:

        def clean(v: object) -> object:
            if isinstance(v, float) and not math.isfinite(v):
                return None
            if isinstance(v, dict):
                return {k: clean(x) for k, x in v.items()}
            if isinstance(v, list):
                return [clean(x) for x in v]
            return v

        print(json.dumps(clean(res.to_dict())))
    else:
        print(format_result(res))
    sys.stdout.flush()
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add ``tracker friction-id``."""
    from tracker.cli import command_help

    p = subparsers.add_parser("friction-id", help=command_help("friction-id"))
    p.add_argument("--axis", required=True, choices=("pan", "tilt"))
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--hidden-effects", metavar="RIG.json", default=None, help="simulated rig config with hidden effects"
    )
    p.add_argument(
        "--effects", default="", help="hidden effects of the simulated rig on this axis, comma-separated"
    )
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="a hidden effect's parameter")
    p.add_argument(
        "--voltages", type=int, default=10, help="constant-voltage runs per direction (default 10)"
    )
    p.add_argument("--driver", default=None, metavar="URL",
                   help="run on a DC rig's motor controller board: serial:///dev/ttyUSB0?baud=1000000")
    p.add_argument("--gear-ratio", type=float, default=None,
                   help="with --driver: motor revolutions per load revolution of this axis (default 17.01)")
    p.set_defaults(func=run)


__all__ = ["format_result", "register", "run"]
