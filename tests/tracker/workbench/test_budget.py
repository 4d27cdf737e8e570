"""The error budget and the floor it rests on, against ground truth: the sensor noise and the load
disturbance read from a log are those the generator put there; the budget's parts add up."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.truthgen.matrix import generate_case
from tracker.plant.model import AxisModel
from tracker.workbench.budget import ErrorBudget, error_budget
from tracker.workbench.compare.floor import SensorNoise, disturbance_amplitude, disturbance_rms_nm
from tracker.workbench.experiments.experiments import generate_measurement, random_hidden_model
from tracker.workbench.fit.fit import fit_model
from tracker.workbench.measurements.states import estimate_states, with_load_observer
from tracker.workbench.versions import ModelVersion


@pytest.mark.parametrize("case_id", ["gravity-000", "clean-005", "clean-002"])
def test_white_noise_is_read_as_the_generator_made_it(case_id: str) -> None:
    log, truth = generate_case(case_id)
    true_sd = float(truth["noise"]["theta_std_rad"])  # type: ignore[index]
    s = SensorNoise.from_log(np.asarray(log.theta))
    assert s.encoder_step_rad == pytest.approx(2 * math.pi / float(truth["encoder_counts_per_rev"]), rel=1e-6)  # type: ignore[arg-type]
    if true_sd > 0:
        assert s.white_noise_rad == pytest.approx(true_sd, rel=0.05)
    else:
        assert s.white_noise_rad < 0.05 * s.encoder_step_rad


@pytest.mark.parametrize(("truth_seed", "run_seed"), [(11, 6), (21, 3)])
def test_load_disturbance_is_read_as_the_practice_rig_made_it(truth_seed: int, run_seed: int) -> None:
    truth = random_hidden_model("pan", ["offset"], seed=truth_seed)
    meas = generate_measurement(truth, duration_s=10.0, seed=run_seed)  # 0.002 N·m, 50 ms
    model = fit_model(meas, AxisModel.for_axis("pan", ("offset",))).model
    est = with_load_observer(estimate_states(meas, model), model, meas)
    amp = disturbance_amplitude(meas, model, est, 0.03, SensorNoise.from_log(meas.theta_rad))
    assert disturbance_rms_nm(amp, meas.n) == pytest.approx(0.002, rel=0.25)


def test_the_parts_add_up_and_a_right_model_ends_at_the_floor() -> None:
    truth = random_hidden_model("pan", ["offset"], seed=21)
    meas = generate_measurement(truth, duration_s=10.0, seed=3)
    base = fit_model(meas, AxisModel.for_axis("pan")).model
    right = fit_model(meas, AxisModel.for_axis("pan", ("offset",))).model
    b1 = error_budget(meas, base, replicas=3)
    assert b1 is not None
    b2 = error_budget(meas, right, [("base", b1.rms_deg)], "+offset", replicas=3)
    assert b2 is not None
    assert not b1.at_floor and b2.at_floor and b2.consistent
    assert b1.rms_deg**2 == pytest.approx(b1.floor_deg**2 + b1.left_deg**2, rel=1e-9)
    assert b1.floor_deg**2 == pytest.approx(
        b1.quantization_deg**2 + b1.noise_deg**2 + b1.disturbance_deg**2, rel=1e-9
    )
    ((change, deg),) = b2.explained
    assert change == "+offset" and deg**2 == pytest.approx(b1.rms_deg**2 - b2.rms_deg**2, rel=1e-9)
    # against the newest floor, version 1's bar is its own error: floor + what is left
    r1 = b1.rebased(b2)
    total = sum(ms for _, ms in r1.segments_deg2())
    assert total == pytest.approx(b1.rms_deg**2, rel=1e-6)
    assert ErrorBudget.from_dict(b2.to_dict()) == b2
    v = ModelVersion(2, right, "+offset", 99.9, 99.0, b2.rms_deg, budget=b2)
    assert ModelVersion.from_dict(v.to_dict(), "test").budget == b2
