"""The break-away from rest measured as a level (tracker.workbench.diagnose.breakaway) on logs of
the independent truth generator (development half of the blind matrix, default seed)."""

from __future__ import annotations

from typing import Any

from tests.truthgen.matrix import generate_case
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.breakaway import BreakAway, analyse_breakaway
from tracker.workbench.measurements.data import Measurement


def _breakaway(case_id: str) -> tuple[dict[str, Any], AxisModel, BreakAway | None]:
    log, truth = generate_case(case_id)
    meas = Measurement(log.t, log.u, log.theta, case_id)
    model = AxisModel.for_axis(str(truth["axis"]), gain_nm_per_v=float(truth["gain_nm_per_v"]))  # type: ignore[arg-type]
    return truth, model, analyse_breakaway(meas, model)


def test_stiction_held_by_a_closed_loop_command_is_measured_at_its_level() -> None:
    """Regression: dev stiction-003 (PD + feed-forward at 500 Hz, break-away 63 % above Coulomb).
    The command crept past the break-away at a rate that changed through the lag, so the old
    measure (lag × the last 20 ms's rate) found −2 mN·m ± 10 (nothing); the torque applied at
    the moment of the break, less the model's Coulomb, finds the excess."""
    truth, model, ba = _breakaway("stiction-003")
    assert ba is not None and ba.count >= 5
    true_excess = truth["params"]["stiction.static_torque"] - model.params["coulomb.torque"]
    assert true_excess > 0
    assert 0.5 * true_excess < ba.static_excess_nm < 2.0 * true_excess
    assert ba.static_t > 3.0


def test_a_clean_karnopp_log_holds_nothing_above_coulomb() -> None:
    truth, model, ba = _breakaway("clean-000")
    assert not truth["hidden"] and truth["friction_law"] == "karnopp"
    assert ba is not None and ba.count >= 5
    assert abs(ba.static_t) < 2.0
    assert abs(ba.static_excess_nm) < 0.1 * model.params["coulomb.torque"]
