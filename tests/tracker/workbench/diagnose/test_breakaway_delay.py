"""Starts after voltage steps behind a drive delay are no creeping starts (breakaway.py).

The truth generator's axis (its own integrator, Karnopp friction, no static friction) driven
open loop by voltage steps past Coulomb, with a 15 ms delay, on a 500-count encoder at 500 Hz:
after a step the torque reaches the axis 15 ms later and the axis needs another 15-30 ms to
reach the next count, so the step comes 28-46 ms before the encoder changes, before the window
in which the break-away analysis looks for a jump of the command. Judged against the model with
the delay (a second round after ``fit --effects delay``), each such start's break-away was the
step's level: here 28 "creeping" starts +0.094 ± 0.025 N·m over Coulomb (a log of the same kind,
0.12 ± 0.03 in 18 starts, had static friction "established at rest" and named: a false alarm).
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.truthgen.axis import TrueAxis
from tests.truthgen.presets import GAIN_NM_PER_V
from tests.truthgen.run import replay
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.breakaway import analyse_breakaway
from tracker.workbench.measurements.data import Measurement

RATE_HZ = 500.0
PARAMS = {
    "inertia.J": 0.0015,
    "viscous.b": 0.0004,
    "coulomb.torque": 0.057,
    "inertia.motor_fraction": 0.15,
    "quantization.step": 2 * np.pi / 500,
    "delay.seconds": 0.015,
}


def _steps(rng: np.random.Generator, n: int) -> np.ndarray:
    """Pulses of 1.7-3.7 × Coulomb for 50-150 ms, reversing at random, 0.2-0.8 s apart."""
    u, i, sign = np.zeros(n), int(0.5 * RATE_HZ), 1.0
    while i < n:
        sign = -sign if rng.random() < 0.6 else sign
        end = min(n, i + int(rng.uniform(0.05, 0.15) * RATE_HZ))
        u[i:end] = sign * rng.uniform(1.7, 3.7) * PARAMS["coulomb.torque"] / GAIN_NM_PER_V
        i = end + int(rng.uniform(0.2, 0.8) * RATE_HZ)
    return u


@pytest.mark.xfail(
    strict=True,
    reason="known false alarm (issue 9, session 12): the creeping-start test is made before the "
    "encoder's change, not at the break; judging it at the break rejected the closed-loop starts "
    "of test_breakaway.py too (the command swings through zero fast at a reversal, then creeps)",
)
def test_starts_after_steps_behind_a_delay_measure_no_break_away() -> None:
    rng = np.random.default_rng(5)
    u = _steps(rng, int(30 * RATE_HZ))
    axis = TrueAxis(GAIN_NM_PER_V, dict(PARAMS), ["delay"], "karnopp", {})
    log = replay(axis, u, RATE_HZ)
    meas = Measurement(log.t, log.u, log.theta, "steps-delay")
    values = {k: v for k, v in PARAMS.items() if k != "quantization.step"}
    model = AxisModel.for_axis("tilt", ("delay",), values, gain_nm_per_v=GAIN_NM_PER_V)
    ba = analyse_breakaway(meas, model)
    # No start crept up to a break-away: none measured, or no excess over Coulomb beyond 2 se.
    assert ba is None or ba.static_excess_nm < 2.0 * ba.static_excess_se
