"""The residual test against the simulated band: a right model passes, a wrong one fails.

Logs come from the independent generator (`tests/truthgen`, which imports nothing from
tracker): its own integrator, friction laws and controllers. The bounds come only from the
replicas' spread; nothing here sets a threshold.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from tests.truthgen.matrix import generate_case
from tracker.plant.model import AxisModel
from tracker.workbench.compare.compare import compare_model
from tracker.workbench.compare.consistency import agreement, upper_bound
from tracker.workbench.compare.floor import SensorNoise
from tracker.workbench.fit.fit import fit_model
from tracker.workbench.measurements.data import Measurement


@cache
def _case(case_id: str) -> tuple[dict[str, object], Measurement]:
    log, truth = generate_case(case_id)
    return truth, Measurement(log.t, log.u, log.theta, case_id)


def _model(truth: dict[str, object], effects: tuple[str, ...], **kw: object) -> AxisModel:
    return AxisModel.for_axis(str(truth["axis"]), effects, gain_nm_per_v=float(truth["gain_nm_per_v"]), **kw)  # type: ignore[arg-type]


def test_the_sensor_is_read_from_the_log() -> None:
    truth, meas = _case("clean-002")
    q = 2 * np.pi / float(truth["encoder_counts_per_rev"])  # type: ignore[arg-type]
    s = SensorNoise.from_log(meas.theta_rad)
    assert s.encoder_step_rad == pytest.approx(q, rel=1e-6)
    assert s.white_noise_rad < q / np.sqrt(12)  # no noise before the encoder: small next to q²/12


def test_upper_bound_is_a_prediction_interval() -> None:
    x = np.array([1.0, 1.1, 0.9, 1.0, 1.0])
    b = upper_bound(x, 0.99)
    assert 1.0 < b < 1.6
    assert upper_bound(np.array([1.0])) == np.inf


def test_right_model_is_consistent_and_a_large_coulomb_error_is_not() -> None:
    truth, meas = _case("clean-002")
    right = fit_model(meas, _model(truth, ())).model
    v = compare_model(meas, right, replicas=5).verdict
    assert v is not None
    assert v.consistent, v.explanation()
    assert "nothing is missing" in agreement(v, None)
    # the same structure with Coulomb friction at half its fitted value (J, b refitted around it)
    fc = right.params["coulomb.torque"]
    wrong_start = _model(truth, (), overrides={"coulomb.torque": 0.5 * fc})
    wrong = fit_model(meas, wrong_start, free=["inertia.J", "viscous.b"]).model
    w = compare_model(meas, wrong, replicas=5).verdict
    assert w is not None
    assert not w.consistent, w.explanation()
    assert w.rms_rad.ratio > v.rms_rad.ratio


def test_missing_gravity_fails_and_the_model_with_it_passes() -> None:
    truth, meas = _case("gravity-000")
    assert truth["hidden"] == ["gravity"]
    right = fit_model(meas, _model(truth, ("gravity",))).model
    v = compare_model(meas, right, replicas=5).verdict
    assert v is not None and v.consistent, v.explanation()
    wrong = fit_model(meas, _model(truth, ())).model
    w = compare_model(meas, wrong, replicas=5).verdict
    assert w is not None and not w.consistent, w.explanation()
    assert w.failing_regimes
    assert "agree" in agreement(w, "gravity")
