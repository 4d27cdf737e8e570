"""Compare: MATLAB's fit %, k-step prediction against the truth, error by regime."""

import json
import math

import numpy as np
import pytest

from tracker.errors import ConfigError, DataError
from tracker.plant.model import AxisModel
from tracker.workbench.compare.compare import compare_model, fit_percent
from tracker.workbench.compare.regimes import regime_error
from tracker.workbench.experiments.excite import closed_loop_log
from tracker.workbench.measurements.data import Measurement


def test_fit_percent_matches_a_hand_computation() -> None:
    y = np.array([0.0, 1.0, 2.0, 3.0])
    y_hat = np.array([0.0, 1.0, 2.0, 4.0])
    # ‖y − ŷ‖ = 1, ‖y − mean y‖ = √5  →  100·(1 − 1/√5)
    assert fit_percent(y, y_hat) == pytest.approx(100.0 * (1.0 - 1.0 / math.sqrt(5.0)))
    assert fit_percent(y, y) == 100.0
    assert fit_percent(y, np.full(4, y.mean())) == pytest.approx(0.0)


@pytest.fixture(scope="module")
def offset_run() -> Measurement:
    true = AxisModel.for_axis("pan", ["quantization", "offset"], {"offset.torque": 0.012})
    return closed_loop_log(true, duration_s=20.0, seed=3)


def test_the_true_model_predicts_to_the_encoder_count_and_a_wrong_one_does_not(
    offset_run: Measurement,
) -> None:
    right = compare_model(offset_run, AxisModel.for_axis("pan", ["offset"], {"offset.torque": 0.012}))
    wrong = compare_model(offset_run, AxisModel.for_axis("pan"))
    count = 2 * math.pi / (4 * 500 * 6.3 * 2.7)
    assert right.rms_deg < math.degrees(2 * count)  # quantization plus state-estimate noise only
    assert right.fit_percent > 99.9
    assert wrong.rms_deg > 3 * right.rms_deg
    # The increment fit is the sensitive number: θ's variance hides the error in fit_percent.
    assert right.fit_percent - wrong.fit_percent < 2.0
    assert right.fit_percent_increment - wrong.fit_percent_increment > 4.0


def test_free_simulation_of_an_integrating_plant_drifts(offset_run: Measurement) -> None:
    k_step = compare_model(offset_run, AxisModel.for_axis("pan"))
    free = compare_model(offset_run, AxisModel.for_axis("pan"), mode="free")
    assert free.mode == "free" and free.horizon_s is None
    assert free.rms_deg > 10 * k_step.rms_deg


def test_longer_horizon_lets_a_torque_error_grow(offset_run: Measurement) -> None:
    wrong = AxisModel.for_axis("pan")
    short = compare_model(offset_run, wrong, horizon_s=0.01)
    long = compare_model(offset_run, wrong, horizon_s=0.08)
    assert long.horizon_s == pytest.approx(0.08)
    assert long.rms_deg > 5 * short.rms_deg  # a torque error grows like h²


def test_regime_shares_are_consistent_and_json_follows_the_contract(offset_run: Measurement) -> None:
    res = compare_model(offset_run, AxisModel.for_axis("pan"))
    total = float(np.sum(res.residual_rad**2))
    for name, r in res.regimes.items():
        assert 0.0 <= r.share_of_error_percent <= 100.0 + 1e-9, name
        assert r.samples == round(r.fraction_of_time * offset_run.n), name
    moving, hold = res.regimes["moving"], res.regimes["hold"]
    assert moving.share_of_error_percent + hold.share_of_error_percent == pytest.approx(100.0)
    assert moving.samples + hold.samples == offset_run.n
    shares = sum(r.share_of_error_percent for _, r in res.breakdown.position_bins)
    assert shares == pytest.approx(100.0)
    d = json.loads(json.dumps(res.to_dict()))
    assert isinstance(d["fit_percent"], float) and isinstance(d["rms_deg"], float)
    assert set(d["regimes"]) >= {"reversal", "low_speed", "high_speed", "high_accel", "hold"}
    assert total > 0


def test_regime_error_by_hand() -> None:
    r = np.array([1.0, 1.0, 2.0, 0.0])
    e = regime_error(r, np.array([False, False, True, True]))
    assert e.share_of_error_percent == pytest.approx(100.0 * 4.0 / 6.0)
    assert e.rms_deg == pytest.approx(math.degrees(math.sqrt(2.0)))
    assert e.fraction_of_time == 0.5 and e.concentration == pytest.approx(4.0 / 3.0)


def test_backlash_error_concentrates_at_reversals() -> None:
    true = AxisModel.for_axis("pan", ["quantization", "backlash"], {"backlash.width": 0.02})
    meas = closed_loop_log(true, duration_s=20.0, seed=9)
    res = compare_model(meas, AxisModel.for_axis("pan"))
    assert res.regimes["reversal"].concentration > 1.5


def test_bad_horizon_and_mode_are_errors(offset_run: Measurement) -> None:
    with pytest.raises(ConfigError, match="horizon"):
        compare_model(offset_run, AxisModel.for_axis("pan"), horizon_s=-1.0)
    with pytest.raises(DataError, match="quarter"):
        compare_model(offset_run, AxisModel.for_axis("pan"), horizon_s=100.0)
    with pytest.raises(ConfigError, match="mode"):
        compare_model(offset_run, AxisModel.for_axis("pan"), mode="sideways")  # type: ignore[arg-type]
