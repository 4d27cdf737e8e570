"""The axis model: seed transfer function, catalogue integrity, parameter validation."""

import math

import numpy as np
import pytest

from tracker.errors import ConfigError
from tracker.plant.effects import BASE_EFFECTS, CATALOGUE, OPTIONAL_EFFECTS, get_param
from tracker.plant.model import AxisModel
from tracker.plant.params import PAN, TILT


def test_linearised_pan_model_is_the_seeds_transfer_function() -> None:
    """Seed eq. 4.3: G_pan(s) = 25.9 / (s² + 0.297 s)."""
    tf = AxisModel.for_axis("pan").linearised_tf()
    num = np.ravel(tf.num[0][0])
    den = np.ravel(tf.den[0][0])
    assert num[-1] / den[0] == pytest.approx(25.9, abs=0.05)
    assert den[1] / den[0] == pytest.approx(0.297, abs=0.001)
    assert den[2] == 0.0


def test_seed_gain_is_the_product_of_the_datasheet_constants() -> None:
    assert PAN.gain_nm_per_v == pytest.approx(6.3 * 2.7 * 0.0436 * 0.1)
    assert TILT.inertia_kg_m2 < PAN.inertia_kg_m2


def test_every_parameter_has_units_bounds_and_a_default_inside_them() -> None:
    for effect in CATALOGUE.values():
        assert effect.params or effect.name in BASE_EFFECTS
        for p in effect.params:
            assert p.unit, f"{effect.name}.{p.name} has no unit"
            assert p.lower <= p.default <= p.upper, f"{effect.name}.{p.name} default out of bounds"


@pytest.mark.parametrize(
    "name",
    [
        "inertia.J",
        "viscous.b",
        "coulomb.torque",
        "coulomb_asymmetry.negative",
        "viscous_asymmetry.negative",
        "offset.torque",
        "stiction.static_torque",
        "stiction.velocity",
        "gravity.torque",
        "gravity.phase",
        "delay.seconds",
        "saturation.limit",
        "ripple.amplitude",
        "ripple.cycles_per_rev",
        "ripple.phase",
        "backlash.width",
        "compliance.frequency",
        "compliance.damping",
    ],
)
def test_the_contract_parameter_names_exist(name: str) -> None:
    assert get_param(name).name == name.split(".")[1]


def test_unknown_effect_and_out_of_bounds_values_are_refused_with_the_name() -> None:
    with pytest.raises(ConfigError, match="unknown effect 'wobble'"):
        AxisModel.for_axis("pan", ["wobble"])
    with pytest.raises(ConfigError, match="delay.seconds|seconds"):
        AxisModel.for_axis("pan", ["delay"], {"delay.seconds": 5.0})
    with pytest.raises(ConfigError, match="not a finite"):
        AxisModel.for_axis("pan", [], {"viscous.b": math.nan})
    with pytest.raises(ConfigError, match="unknown axis"):
        AxisModel.for_axis("roll")


def test_adding_an_asymmetry_starts_symmetric_and_removing_an_effect_drops_its_params() -> None:
    m = AxisModel.for_axis("pan", ["coulomb_asymmetry"])
    assert m.params["coulomb_asymmetry.negative"] == m.params["coulomb.torque"]
    m2 = m.with_effect("gravity").without_effect("coulomb_asymmetry")
    assert m2.effects == ("gravity",)
    assert "coulomb_asymmetry.negative" not in m2.params
    assert set(OPTIONAL_EFFECTS).isdisjoint(BASE_EFFECTS)


def test_rebuilding_a_model_keeps_a_fitted_asymmetry() -> None:
    """Regression: with_params/with_effect reset *_asymmetry.negative to the positive twin."""
    m = AxisModel.for_axis(
        "pan",
        ["coulomb_asymmetry", "viscous_asymmetry"],
        {"coulomb_asymmetry.negative": 0.07, "viscous_asymmetry.negative": 1.2e-3},
    )
    for rebuilt in (
        m.with_params({"viscous.b": 9e-4}),
        m.with_effect("gravity"),
        m.without_effect("gravity"),
    ):
        assert rebuilt.params["coulomb_asymmetry.negative"] == 0.07
        assert rebuilt.params["viscous_asymmetry.negative"] == 1.2e-3
