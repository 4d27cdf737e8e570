"""The closed-loop measurement generator: realistic, reproducible, and the hidden effect is in it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tracker.errors import ConfigError
from tracker.plant.effects.quantization import SEED_ENCODER_STEP_RAD
from tracker.plant.model import AxisModel
from tracker.workbench.experiments.experiments import (
    HIDDEN_RANGES,
    generate_measurement,
    random_hidden_model,
    shape_reference,
)
from tracker.workbench.measurements.data import validate


def test_same_seed_same_log_and_a_valid_quantized_closed_loop_run() -> None:
    m = AxisModel.for_axis("pan")
    a = generate_measurement(m, 8.0, seed=3)
    b = generate_measurement(m, 8.0, seed=3)
    assert np.array_equal(a.theta_rad, b.theta_rad) and np.array_equal(a.u_v, b.u_v)
    validate(a)
    counts = a.theta_rad / SEED_ENCODER_STEP_RAD
    assert np.allclose(counts, np.round(counts), atol=1e-6)  # whole encoder counts
    assert np.all(np.abs(a.u_v) <= 10.0)
    th = a.theta_rad
    assert np.ptp(th) > 1.0  # moves over a wide range ...
    still = np.diff(th) == 0.0
    assert 0.05 < still.mean() < 0.8  # ... with holds
    assert np.std(a.u_v - np.convolve(a.u_v, np.ones(5) / 5, "same")) > 0.03  # dither on the command


def test_the_hidden_effect_changes_the_run() -> None:
    clean = generate_measurement(AxisModel.for_axis("pan"), 6.0, seed=1)
    hidden = generate_measurement(AxisModel.for_axis("pan", ["offset"], {"offset.torque": 0.02}), 6.0, seed=1)
    assert not np.array_equal(clean.theta_rad, hidden.theta_rad)


def test_asymmetric_hidden_friction_survives_the_encoder_setup() -> None:
    # Regression: adding the encoder through AxisModel.with_effect reset the negative Coulomb
    # torque to the positive one, so the "hidden" asymmetry was not in the data at all.
    sym = generate_measurement(AxisModel.for_axis("pan"), 6.0, seed=2)
    asym = generate_measurement(
        AxisModel.for_axis("pan", ["coulomb_asymmetry"], {"coulomb_asymmetry.negative": 0.08}), 6.0, seed=2
    )
    assert not np.array_equal(sym.theta_rad, asym.theta_rad)


@pytest.mark.parametrize("effect", sorted(HIDDEN_RANGES))
def test_random_hidden_parameters_lie_in_their_ranges(effect: str) -> None:
    m = random_hidden_model("pan", [effect], seed=7)
    assert m.has(effect)
    base = AxisModel.for_axis("pan").params
    for name, (lo, hi, how) in HIDDEN_RANGES[effect].items():
        v = m.params[f"{effect}.{name}"]
        scale = {"fc": base["coulomb.torque"], "b": base["viscous.b"]}.get(how, 1.0)
        v = abs(v) if how == "signed" else v
        assert lo * scale - 1e-12 <= v <= hi * scale + 1e-12


def test_unknown_hidden_effect_and_too_short_runs_are_refused() -> None:
    with pytest.raises(ConfigError, match="warp"):
        random_hidden_model("pan", ["warp"], 0)
    with pytest.raises(ConfigError, match="200 samples"):
        generate_measurement(AxisModel.for_axis("pan"), 0.1)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-2.0, 2.0), min_size=2, max_size=8), st.floats(0.5, 6.0), st.floats(20.0, 300.0))
def test_shaped_reference_respects_speed_and_acceleration_limits(
    levels: list[float], vmax: float, amax: float
) -> None:
    ref = np.repeat(np.array(levels), 300)
    p, v, a = shape_reference(ref, 1e-3, vmax, amax)
    assert np.all(np.abs(v) <= vmax + 1e-9)
    assert np.all(np.abs(a) <= amax + 1e-9)
    assert np.allclose(np.diff(p), v[1:] * 1e-3)
