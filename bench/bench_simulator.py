"""Benchmark: simulator speed, open loop (base, every effect on) and closed loop (controller + twin).

Prints wall time for one hour of simulated 1 kHz operation on one core. Run:
``.venv/bin/python bench/bench_simulator.py``.
"""

from __future__ import annotations

import math
import time

import numpy as np

from tracker.control.closed_loop import N_REC, history_length, run_chunk
from tracker.control.design import design_controller
from tracker.control.limits import SoftLimits
from tracker.control.loop import new_state, pack_controller
from tracker.control.pointing import SCRIPT_S, script_targets
from tracker.control.trajectory import DEFAULT_LIMITS
from tracker.plant.effects import OPTIONAL_EFFECTS
from tracker.plant.model import AxisModel
from tracker.plant.simulate import initial_state, pack_params, simulate

DT = 1e-3
HOUR_S = 3600.0


def best_of(fn, repeats: int = 3) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def every_effect(axis: str) -> AxisModel:
    """The axis with every optional effect on, at non-trivial values."""
    return AxisModel.for_axis(
        axis,
        OPTIONAL_EFFECTS,
        {
            "gravity.torque": 0.02,
            "offset.torque": 0.005,
            "stiction.static_torque": 0.07,
            "delay.seconds": 0.002,
            "saturation.limit": 9.0,
            "ripple.amplitude": 0.005,
            "backlash.width": 0.002,
        },
    )


def open_loop(model: AxisModel) -> float:
    n = int(HOUR_S / DT)
    t = np.arange(n) * DT
    u = 2.0 * np.sin(2 * math.pi * 0.2 * t) + 0.5 * np.sign(np.sin(2 * math.pi * 1.3 * t))
    simulate(model, u[:1000], DT)  # compile / load the cache
    return best_of(lambda: simulate(model, u, DT))


def closed_loop(axis: str, plant: AxisModel) -> float:
    model = AxisModel.for_axis(axis)
    gains = design_controller(model, axis=axis).gains
    one = script_targets(axis, SCRIPT_S, DT)
    rec = np.empty((one.size, N_REC))

    def hour() -> None:
        cp = pack_controller(model, gains, DT, SoftLimits.for_axis(axis), DEFAULT_LIMITS[axis])
        pp = pack_params(plant, DT)
        x, cs = initial_state(), new_state()
        hist = np.zeros(history_length(pp, DT))
        for _ in range(int(HOUR_S / SCRIPT_S)):
            run_chunk(pp, cp, cs, x, hist, one, np.zeros(0), True, math.inf, rec)

    return best_of(hour, repeats=2)


def main() -> None:
    print("one hour of simulated 1 kHz operation (3.6 M samples), best wall time on one core")
    for axis in ("pan", "tilt"):
        base = AxisModel.for_axis(axis, ["quantization"])
        full = every_effect(axis)
        print(f"{axis:5s} open loop,  base model          : {open_loop(base):6.3f} s")
        effects = ", ".join(full.effects)
        print(f"{axis:5s} open loop,  every effect on     : {open_loop(full):6.3f} s  ({effects})")
        print(
            f"{axis:5s} closed loop, base twin          : {closed_loop(axis, base):6.3f} s  (observer_pd_ff)"
        )
        print(f"{axis:5s} closed loop, every effect on    : {closed_loop(axis, full):6.3f} s")


if __name__ == "__main__":
    main()
