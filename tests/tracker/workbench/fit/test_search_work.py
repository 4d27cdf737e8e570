"""The fit's shortcuts change how much it evaluates, never what it finds."""

import math

import numpy as np
import pytest
from scipy.optimize import least_squares

from tracker.plant.model import AxisModel
from tracker.workbench.experiments.excite import closed_loop_log
from tracker.workbench.fit import search
from tracker.workbench.fit.short import short_least_squares
from tracker.workbench.measurements.states import estimate_states


def _rosenbrock_residuals(counter: list[int]):  # type: ignore[no-untyped-def]
    def fun(x: np.ndarray) -> np.ndarray:
        counter[0] += 1
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0], 0.3 * (x[2] - x[1])])

    return fun


LOWER = np.full(3, -5.0)
UPPER = np.full(3, 5.0)
STEPS = np.full(3, 1e-2)
X0 = np.array([-1.2, 1.0, 0.5])


def _reference(calls: list[int], max_nfev: int, **options: object):  # type: ignore[no-untyped-def]
    """scipy's own least_squares on the same problem, as the short fit calls it."""
    return least_squares(
        _rosenbrock_residuals(calls),
        X0,
        bounds=(LOWER, UPPER),
        method="trf",
        x_scale=1.0,
        diff_step=STEPS,
        max_nfev=max_nfev,
        **options,
    )


@pytest.mark.parametrize("max_nfev", [2, 4, 7])
def test_a_short_fit_ends_where_least_squares_ends_without_its_last_jacobian(max_nfev: int) -> None:
    ref_calls, calls = [0], [0]
    ref = _reference(ref_calls, max_nfev)
    got = short_least_squares(_rosenbrock_residuals(calls), X0, LOWER, UPPER, STEPS, max_nfev)
    np.testing.assert_array_equal(got.x, ref.x)
    assert got.cost == ref.cost
    assert got.status == ref.status == 0
    # The Jacobian least_squares differences at its last point (3 evaluations) is not computed.
    assert calls[0] == ref_calls[0] - 3


def test_a_stop_rule_stops_where_a_callback_would_before_the_jacobian() -> None:
    def callback(intermediate_result):  # type: ignore[no-untyped-def]
        if intermediate_result.cost < 2.0:
            raise StopIteration

    ref_calls, calls = [0], [0]
    ref = _reference(ref_calls, 50, callback=callback)
    got = short_least_squares(
        _rosenbrock_residuals(calls), X0, LOWER, UPPER, STEPS, 50, lambda x, cost, nfev: cost < 2.0
    )
    assert ref.status == got.status == -2
    np.testing.assert_array_equal(got.x, ref.x)
    assert got.cost == ref.cost
    assert calls[0] == ref_calls[0] - 3


def test_a_converged_short_fit_is_least_squares_own_answer() -> None:
    ref = least_squares(
        _rosenbrock_residuals([0]), X0, bounds=(LOWER, UPPER), method="trf", x_scale=1.0, diff_step=STEPS
    )
    got = short_least_squares(_rosenbrock_residuals([0]), X0, LOWER, UPPER, STEPS, 1000)
    assert got.status == ref.status > 0
    np.testing.assert_array_equal(got.x, ref.x)


@pytest.fixture(scope="module")
def belt_log():  # type: ignore[no-untyped-def]
    truth = AxisModel.for_axis(
        "pan", ["quantization", "compliance"], {"compliance.frequency": 15.0, "compliance.damping": 0.1}
    )
    meas = closed_loop_log(truth, duration_s=8.0, seed=5, disturbance_nm=5e-4)
    return meas, estimate_states(meas)


def test_the_bounded_resonance_scan_refines_the_basins_the_full_scan_does(belt_log, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The coarse profile abandons frequencies dearer than its third-lowest confirmed minimum:
    the basins refined, and their models, are those of the profile computed in full."""
    meas, est = belt_log
    start = AxisModel.for_axis("pan", ["compliance"])
    calls: list[float] = []
    cost = search.window_cost

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        c = cost(*args, **kwargs)
        calls.append(c)
        return c

    monkeypatch.setattr(search, "window_cost", counted)
    bounded = search.search_resonance(meas, est, start, True, 30)
    abandoned = sum(1 for c in calls if math.isinf(c))
    monkeypatch.setattr(search, "_profile_bound", lambda minima: math.inf)
    calls.clear()
    full = search.search_resonance(meas, est, start, True, 30)
    assert [m.params for m in bounded] == [m.params for m in full]
    assert abandoned > sum(1 for c in calls if math.isinf(c))


def test_profile_bound_is_the_third_lowest_confirmed_minimum() -> None:
    assert search._profile_bound([3.0, 1.0]) == math.inf
    assert search._profile_bound([3.0, 1.0, 5.0, 2.0]) == 3.0
    assert search._is_local_minimum([2.0, 1.0, 3.0], 1)
    assert search._is_local_minimum([1.0, 2.0], 0)
    assert not search._is_local_minimum([1.0, 2.0], 1)
