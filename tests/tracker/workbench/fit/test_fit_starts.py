"""Starting values of the fit: what the data says must survive into the nonlinear fit."""

import math

import pytest

from tracker.plant.model import AxisModel
from tracker.workbench.experiments.excite import closed_loop_log
from tracker.workbench.fit.fit import default_free, fit_model
from tracker.workbench.fit.search import search_start
from tracker.workbench.measurements.states import estimate_states

TRUE_GRAVITY = {"gravity.torque": 0.06, "gravity.phase": 2.0}


@pytest.fixture(scope="module")
def gravity_log():  # type: ignore[no-untyped-def]
    truth = AxisModel.for_axis("pan", ["gravity"], TRUE_GRAVITY)
    return closed_loop_log(truth, duration_s=20.0, seed=3, disturbance_nm=5e-4)


def test_start_keeps_the_gravity_phase_inverse_dynamics_found(gravity_log) -> None:  # type: ignore[no-untyped-def]
    """Regression: the start kept the amplitude but dropped the phase (always 0), so a hidden
    unbalance at phase 2 rad started as a torque at the wrong angle, lost to 'no gravity' and
    the fit ended at T = 0 (blind check, gravity seed 0: torque −100 %)."""
    model = AxisModel.for_axis("pan", ["gravity"])
    start = search_start(gravity_log, estimate_states(gravity_log), model, default_free(model), 30).model
    assert start.params["gravity.phase"] == pytest.approx(TRUE_GRAVITY["gravity.phase"], abs=0.1)
    assert start.params["gravity.torque"] == pytest.approx(TRUE_GRAVITY["gravity.torque"], rel=0.1)


def test_adding_gravity_recovers_it_from_the_default_start(gravity_log) -> None:  # type: ignore[no-untyped-def]
    fit = fit_model(gravity_log, AxisModel.for_axis("pan", ["gravity"]))
    assert fit.params["gravity.torque"] == pytest.approx(0.06, rel=0.1)
    wrapped = math.remainder(fit.params["gravity.phase"] - 2.0, 2 * math.pi)
    assert abs(wrapped) < 0.1


def test_a_wide_dead_band_is_found_although_inverse_dynamics_fails_through_it() -> None:
    """Regression: with a 1.4° dead band inverse dynamics returned J ten times too small; the
    backlash grid ran on that model, found nothing and the fit ended at width 0 (blind check,
    backlash seed 1: width −100 %)."""
    truth = AxisModel.for_axis("pan", ["backlash"], {"backlash.width": 0.025})
    log = closed_loop_log(truth, duration_s=20.0, seed=5, disturbance_nm=5e-4)
    fit = fit_model(log, AxisModel.for_axis("pan", ["backlash"]))
    assert fit.params["backlash.width"] == pytest.approx(0.025, rel=0.15)
