"""The one-pass observed-window predictor gives exactly the stepwise path's numbers."""

import numpy as np
import pytest

from tracker.errors import DataError
from tracker.plant.model import AxisModel
from tracker.plant.simulate import predict_windows
from tracker.workbench.experiments.excite import closed_loop_log
from tracker.workbench.measurements.observed import predict_observed
from tracker.workbench.measurements.states import estimate_states, with_load_observer


@pytest.fixture(scope="module")
def belt_log():
    true = AxisModel.for_axis(
        "pan",
        ("quantization", "compliance", "gravity"),
        {"compliance.frequency": 15.0, "compliance.damping": 0.1, "gravity.torque": 0.03},
    )
    meas = closed_loop_log(true, duration_s=3.0, seed=3, disturbance_nm=0.0005)
    return meas, estimate_states(meas)


@pytest.mark.parametrize(
    "effects,params",
    [
        ((), {}),
        (("compliance",), {"compliance.frequency": 22.0, "compliance.damping": 0.3}),
        (
            ("compliance", "gravity", "ripple"),
            {"compliance.frequency": 90.0, "gravity.torque": 0.02, "ripple.amplitude": 0.01},
        ),
        (("backlash", "delay"), {"backlash.width": 0.004, "delay.seconds": 0.0025}),
    ],
)
@pytest.mark.parametrize("stride", [1, 3])
def test_same_numbers_as_observer_then_windows(belt_log, effects, params, stride):
    meas, est = belt_log
    model = AxisModel.for_axis("pan", effects, params)
    k = 30
    starts = np.arange(0, meas.n - k - 1, k * stride, dtype=np.int64)
    x0 = with_load_observer(est, model, meas).initial_states(starts)
    expected = predict_windows(model, meas.u_v, meas.dt_s, starts, k + 1, x0)
    got = predict_observed(model, meas, est, starts, k + 1)
    assert got.shape == (starts.size, k + 1)
    np.testing.assert_array_equal(got, expected)


def test_rejects_unordered_starts(belt_log):
    meas, est = belt_log
    model = AxisModel.for_axis("pan", ("compliance",))
    with pytest.raises(DataError, match="non-decreasing"):
        predict_observed(model, meas, est, np.array([60, 30]), 31)
    with pytest.raises(DataError, match="below"):
        predict_observed(model, meas, est, np.array([meas.n]), 31)
