"""The engine passes the site's guard margin to both axes and switches on the belt guard for a
model with a belt."""

import asyncio
import math

import pytest

from tracker.control.limits import BELT_LOAD_TORQUE_NM, GUARD_MARGIN_RAD, belt_guard_lines
from tracker.drivers.sim import SimDriver
from tracker.engine import Engine, EngineConfig
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel

BELT = {"compliance.frequency": 15.0, "compliance.damping": 0.1}


def belt_rig() -> SimDriver:
    return SimDriver(
        {
            "pan": AxisModel.for_axis("pan", ["quantization"]),
            "tilt": AxisModel.for_axis("tilt", ["quantization", "compliance"], BELT),
        }
    )


def test_the_site_guard_margin_reaches_both_axes() -> None:
    e = Engine(SimDriver(), EngineConfig(guard_margin_rad=0.05))
    assert e.limits("pan").guard_margin_rad == 0.05 and e.limits("tilt").guard_margin_rad == 0.05
    assert Engine(SimDriver()).limits("tilt").guard_margin_rad == GUARD_MARGIN_RAD


@pytest.mark.parametrize("margin", [-0.01, float("nan"), 1.0])
def test_a_bad_guard_margin_is_refused_naming_it(margin: float) -> None:
    with pytest.raises(ConfigError, match="guard_margin_rad|margin"):
        EngineConfig(guard_margin_rad=margin)


def test_a_model_with_a_belt_keeps_the_load_inside_its_belt_lines() -> None:
    """Pointing at 44.9° tilt on a 15 Hz belt the model knows: the load stops inside the line the
    belt guard keeps (the limit less the margin and twice the unseen twist)."""
    tilt = AxisModel.for_axis("tilt", ["compliance"], BELT)
    drv = belt_rig()
    e = Engine(drv, EngineConfig(models={"pan": AxisModel.for_axis("pan"), "tilt": tilt}))
    e.point(0.0, math.radians(44.9))
    asyncio.run(e.run(realtime=False, duration_s=2.0))
    _, hi = belt_guard_lines(tilt, e.limits("tilt"))
    # The twist margin is real: 2 × 0.03 N·m / k with k = (2π·15 Hz)²·Jm·Jl/J ≈ 1.7 N·m/rad.
    assert e.limits("tilt").upper_rad - hi > 2 * BELT_LOAD_TORQUE_NM / 1.8
    assert math.radians(40.0) < drv.load_angle_rad("tilt") < hi


def test_a_belt_too_soft_for_the_limits_is_refused_and_the_model_stays() -> None:
    e = Engine(SimDriver())
    before = e.model("tilt")
    soft = AxisModel.for_axis(
        "tilt", ["compliance"], {"compliance.frequency": 1.0, "compliance.damping": 0.1}
    )
    with pytest.raises(ConfigError, match="1 Hz.*no room"):
        e.set_model("tilt", soft)
    assert e.model("tilt") is before
