"""How deep the live friction sweep's first move goes when the host stalls during it.

The emulated serial rig (the board and its twin on a pty), the driver at 250 Hz with a 1 s
watchdog in its URL (as the live job's tests run it), the sweep lent to the driver on pan with
the service's guard lines (±89.8°). Once the pan has passed ``--onset`` degrees on its way
to -0.85 of the limit, the host thread sleeps ``stall`` seconds (``inf``: it never ticks again);
the deepest load angle the twin reached over the next 3 s is reported with its margin to the
soft limit (90°) and to the end stop (95°), and the faults the driver latched.

    PYTHONPATH=/work/main python bench/bench_sweep_stall.py            # before
    python bench/bench_sweep_stall.py [--host-limits-only]            # after (board limits on/off)
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path
from typing import Any

from tracker.drivers import motor_protocol as mp
from tracker.drivers.motor_board import MotorBoard
from tracker.drivers.motor_emulator import MotorEmulator
from tracker.drivers.serial_motor import SerialMotorDriver
from tracker.drivers.spec import parse_driver_url
from tracker.workbench.experiments.friction_id import friction_sweep

LINES = (math.radians(-89.8), math.radians(89.8))
SOFT_DEG, STOP_DEG = 90.0, 95.0


class OldBoard(MotorBoard):
    """A board without the limit commands: ERR 3 to ``L`` and ``B`` (a protocol-1 board)."""

    def _act(self, line: mp.Line, now: float) -> bytes:
        if line.verb in ("L", "B"):
            raise mp.FramingError(mp.ERR_UNKNOWN_VERB, f"unknown verb {line.verb}", line.seq)
        return super()._act(line, now)


def one(stall_s: float, onset_deg: float, old_board: bool,
        lines: bool) -> tuple[float, tuple[str, ...], bool]:
    """(deepest pan angle in degrees, the driver's faults, whether the stall happened)."""
    with tempfile.TemporaryDirectory() as tmp:
        emu = MotorEmulator(OldBoard() if old_board else None, pty_link=Path(tmp) / "ttyRIG")
        twin = emu.board.twin
        deepest = [0.0]
        step = twin.step

        def tracked(volts: dict[str, float]) -> None:
            step(volts)
            deepest[0] = min(deepest[0], twin.load_rad("pan"))

        twin.step = tracked  # type: ignore[method-assign,assignment]
        emu.start()
        d = SerialMotorDriver(parse_driver_url(f"serial://{emu.path}?baud=1000000&rate=250&watchdog_ms=1000"),
                              limits_rad={"pan": LINES, "tilt": (-0.78, 0.78)})
        try:
            d.start()
            d.wait_ready(5.0)
            d.enable()
            for _ in range(10):
                d.tick()
            kw: dict[str, Any] = {"limits_rad": LINES} if lines else {}  # as the live job (not on main)
            sweep = friction_sweep("pan", d.sample_period_s, (d.read_encoder("pan"), d.sample_time_s),
                                   travel_rad=0.85 * LINES[1], voltages_per_direction=4, **kw)
            d.take_over("bench", "pan", sweep)
            stalled = False
            end = time.monotonic() + 4.0
            while time.monotonic() < end:
                if not stalled and d.read_encoder("pan") < math.radians(onset_deg):
                    stalled = True
                    if math.isinf(stall_s):
                        time.sleep(3.0)
                        break
                    time.sleep(stall_s)
                    end = time.monotonic() + 3.0
                d.tick()
            emu.board.catch_up()
            return math.degrees(deepest[0]), d.faults(), stalled
        finally:
            d.hand_back()
            d.close()
            emu.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stalls", default="0.03,0.06,0.1,1,inf")
    ap.add_argument("--onsets", default="-2,-30,-60", help="degrees the pan has passed when the host stalls")
    ap.add_argument("--host-limits-only", action="store_true", help="a board that refuses L/B")
    ap.add_argument("--lines", action="store_true",
                    help="the sweep gets the guard lines as its limits (as the live job; else the travel)")
    args = ap.parse_args()
    print(f"{'stall s':>8} {'onset°':>7} {'deepest°':>9} {'to soft°':>9} {'to stop°':>9}  faults")
    for stall in (float(x) for x in args.stalls.split(",")):
        for onset in (float(x) for x in args.onsets.split(",")):
            deep, faults, stalled = one(stall, onset, args.host_limits_only, args.lines)
            said = "; ".join(f[-70:] for f in faults) or "-"
            print(f"{stall:>8g} {onset:>7g} {deep:>9.2f} {SOFT_DEG + deep:>9.2f} {STOP_DEG + deep:>9.2f}  "
                  f"{'' if stalled else '(no stall) '}{said}", flush=True)


if __name__ == "__main__":
    main()
