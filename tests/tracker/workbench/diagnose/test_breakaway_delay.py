"""Starts after voltage steps behind a drive delay are no creeping starts (breakaway.py).

The truth generator's axis (its own integrator, Karnopp friction, no static friction) driven
open loop by voltage steps past Coulomb, with a 15 ms delay, on a 500-count encoder at 500 Hz:
after a step the torque reaches the axis 15 ms later and the axis needs another 15-30 ms to
reach the next count, so the step comes 28-46 ms before the encoder changes, before the window
in which the break-away analysis looks for a jump of the command. Judged against the model with
the delay (a second round after ``fit --effects delay``), each such start's break-away was the
step's level: here 28 "creeping" starts +0.094 ± 0.025 N·m over Coulomb (a log of the same kind,
0.12 ± 0.03 in 18 starts, had static friction "established at rest" and named: a false alarm).
The command was flat to rounding through the 20 ms the creep test looks at. Static friction gives
way only while the torque changes, so a break placed on a plateau happened where the plateau
began: after a step, the start bounds the break-away from above and measures no level
(``breakaway._broke_at_a_step``).
"""

from __future__ import annotations

import numpy as np

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


def _staircase_ramps(rng: np.random.Generator, n: int) -> np.ndarray:
    """Ramps from rest up to 2.5 × Coulomb and back, each way in turn, in steps of 1/50 of the
    ramp's height held 10 ms (a command quantized in time and level), 0.3-0.6 s apart."""
    u, i, sign = np.zeros(n), int(0.5 * RATE_HZ), 1.0
    hold = int(0.01 * RATE_HZ)
    while i < n:
        top = rng.uniform(2.0, 3.0) * PARAMS["coulomb.torque"] / GAIN_NM_PER_V
        levels = np.repeat(np.linspace(0.0, top, 51)[1:], hold)
        seg = np.concatenate([levels, levels[::-1]])[: n - i]
        u[i : i + seg.size] = sign * seg
        i += seg.size + int(rng.uniform(0.3, 0.6) * RATE_HZ)
        sign = -sign
    return u


def test_static_friction_behind_a_delay_is_measured_on_a_staircase() -> None:
    """The control: the same axis with static friction 60 % above Coulomb, driven by ramps made of
    small held steps (each 1/50 of the ramp, under ``MAX_JUMP_V``). The command is on a plateau
    wherever the axis breaks away, but the step onto it is small: the torque the axis held just
    before brackets the break-away from below, and the start still measures its level (and the
    same staircase without static friction measures none)."""
    rng = np.random.default_rng(7)
    u = _staircase_ramps(rng, int(30 * RATE_HZ))
    true = {**PARAMS, "stiction.static_torque": 1.6 * PARAMS["coulomb.torque"], "stiction.velocity": 0.02}
    axis = TrueAxis(GAIN_NM_PER_V, dict(true), ["delay", "stiction"], "karnopp", {})
    log = replay(axis, u, RATE_HZ)
    meas = Measurement(log.t, log.u, log.theta, "staircase-stiction-delay")
    values = {k: v for k, v in PARAMS.items() if k != "quantization.step"}
    model = AxisModel.for_axis("tilt", ("delay",), values, gain_nm_per_v=GAIN_NM_PER_V)
    ba = analyse_breakaway(meas, model)
    true_excess = true["stiction.static_torque"] - PARAMS["coulomb.torque"]
    assert ba is not None and ba.count >= 10
    assert 0.7 * true_excess < ba.static_excess_nm < 1.3 * true_excess
    assert ba.static_t > 4.0
    clean = replay(TrueAxis(GAIN_NM_PER_V, dict(PARAMS), ["delay"], "karnopp", {}), u, RATE_HZ)
    ba = analyse_breakaway(Measurement(clean.t, clean.u, clean.theta, "staircase-delay"), model)
    assert ba is not None and abs(ba.static_excess_nm) < 2.0 * ba.static_excess_se
