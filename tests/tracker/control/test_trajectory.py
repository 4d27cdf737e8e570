"""Target shaping: rate/acceleration limits hold, steps are shaped, a 1 Hz sine passes intact."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tracker.control.trajectory import DEFAULT_LIMITS, shape_step

DT = 1e-3


def shape(targets: np.ndarray, v_max: float, a_max: float, lo: float = -10.0, hi: float = 10.0) -> np.ndarray:
    """Shaped reference (n, 3) for a target sequence, with the controller's jump rule."""
    state = np.zeros(3)
    state[0] = targets[0]
    out = np.empty((targets.size, 3))
    prev = targets[0]
    for k, r in enumerate(targets):
        vt = (r - prev) / DT
        prev = r
        if abs(vt) > v_max:
            vt = 0.0
        shape_step(state, r, vt, v_max, a_max, DT, lo, hi)
        out[k] = state
    return out


@settings(max_examples=60, deadline=None)
@given(
    steps=st.lists(st.floats(-1.5, 1.5), min_size=1, max_size=4),
    v_max=st.floats(0.2, 5.0),
    a_max=st.floats(1.0, 100.0),
)
def test_shaped_reference_respects_rate_acceleration_and_position_limits(
    steps: list[float], v_max: float, a_max: float
) -> None:
    targets = np.repeat(np.asarray(steps), 700)
    ref = shape(np.concatenate([[0.0], targets]), v_max, a_max, lo=-1.0, hi=1.0)
    assert np.all(np.abs(ref[:, 1]) <= v_max * (1 + 1e-9))
    assert np.all(np.abs(ref[:, 2]) <= a_max * (1 + 1e-9))
    assert np.all(ref[:, 0] <= 1.0 + 1e-9) and np.all(ref[:, 0] >= -1.0 - 1e-9)


def test_a_step_arrives_without_overshoot_in_the_time_optimal_time() -> None:
    v_max, a_max, step = math.pi, 20.0, math.radians(30.0)
    ref = shape(np.concatenate([[0.0], np.full(2000, step)]), v_max, a_max)
    assert np.max(ref[:, 0]) <= step + 1e-9
    arrive = np.flatnonzero(np.abs(ref[:, 0] - step) < 1e-6)[0] * DT
    t_opt = step / v_max + v_max / a_max  # accelerate, cruise, brake
    if step < v_max**2 / a_max:
        t_opt = 2 * math.sqrt(step / a_max)
    assert arrive == pytest.approx(t_opt, abs=0.02)


@pytest.mark.parametrize(("axis", "amp_deg"), [("pan", 20.0), ("tilt", 10.0)])
def test_the_issues_1hz_sine_passes_unshaped_after_the_start(axis: str, amp_deg: float) -> None:
    lim = DEFAULT_LIMITS[axis]
    t = np.arange(4000) * DT
    target = math.radians(amp_deg) * np.sin(2 * math.pi * t)
    ref = shape(target, lim.rate_rad_s, lim.accel_rad_s2)
    assert np.max(np.abs(ref[1000:, 0] - target[1000:])) < 1e-9
