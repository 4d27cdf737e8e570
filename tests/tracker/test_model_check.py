"""A model offered to a controller must predict the axis's recent motion (issue #11 item 2);
the engine keeps that motion in a ring buffer."""

import asyncio
import math

import numpy as np
import pytest

from tracker.drivers.sim import SimDriver
from tracker.engine import Engine
from tracker.errors import ModelRefused
from tracker.model_check import RECENT_S
from tracker.plant.model import AxisModel
from tracker.recording import RecentLog

BELT = {"compliance.frequency": 15.0, "compliance.damping": 0.1}


def run(engine: Engine, seconds: float) -> None:
    asyncio.run(engine.run(realtime=False, duration_s=seconds))


def moved(drv: SimDriver, pan_deg: tuple[float, ...] = (30.0, -40.0, 20.0)) -> Engine:
    """An engine that pointed pan at ``pan_deg`` in turn, 1.2 s each."""
    e = Engine(drv)
    drv.enable()
    for a in pan_deg:
        e.point(math.radians(a), 0.0)
        run(e, 1.2)
    return e


def pan(**factors: float) -> AxisModel:
    base = AxisModel.for_axis("pan")
    return base.with_params({k: base.params[k] * f for k, f in factors.items()})


def test_recent_log_keeps_the_newest_samples_in_order() -> None:
    log = RecentLog(("pan",), 250)
    t = np.arange(1000.0)
    assert log.measurement("pan") is None
    for k in range(0, 1000, 7):  # chunks that wrap around the ring at odd places
        log.add("pan", t[k : k + 7], 2 * t[k : k + 7], 3 * t[k : k + 7])
    m = log.measurement("pan")
    assert m is not None and m.n == 250
    np.testing.assert_array_equal(m.t_s, t[750:])
    np.testing.assert_array_equal(m.theta_rad, 3 * t[750:])


def test_the_engine_keeps_the_last_ten_seconds() -> None:
    e = moved(SimDriver(), (10.0,) * 10)  # 12 s
    m = e.recent_motion("pan")
    assert m is not None
    assert m.n * m.dt_s == pytest.approx(RECENT_S)
    assert m.t_s[-1] == pytest.approx(e.status().t_s - m.dt_s)


def test_regression_issue_11_a_model_of_a_lighter_axis_is_refused_with_its_figures() -> None:
    """A model with a fifth of the pan inertia, offered after the axis moved: refused, the
    figures say how badly it predicts, and the controller keeps its model."""
    drv = SimDriver()
    e = moved(drv)
    before = e.model("pan")
    with pytest.raises(ModelRefused, match=r"does not predict the last 3\.6 s of pan") as exc:
        e.set_model("pan", pan(**{"inertia.J": 0.2}))
    f = exc.value.figures
    assert f["judged"] is True and f["accepted"] is False
    x, y, z = (f[key] for key in ("candidate_rms_rad", "current_rms_rad", "limit_rad"))
    assert isinstance(x, float) and isinstance(y, float) and isinstance(z, float)
    assert x > 3.0 * z > 10.0 * y
    assert e.model("pan") is before


@pytest.mark.parametrize(
    "factors",
    [{"inertia.J": 1.3}, {"inertia.J": 0.8, "coulomb.torque": 1.2}, {"viscous.b": 3.0}],
    ids=["inertia+30%", "inertia-20%-coulomb+20%", "viscous-x3"],
)
def test_a_model_close_to_the_rig_is_accepted_after_motion(factors: dict[str, float]) -> None:
    e = moved(SimDriver())
    check = e.check_model("pan", pan(**factors))
    assert check.judged and check.accepted, check.describe()
    e.set_model("pan", pan(**factors), check=check)
    assert e.model("pan").params["inertia.J"] == pytest.approx(pan(**factors).params["inertia.J"])


def test_at_rest_a_rigid_model_is_accepted_unchecked_and_a_belt_model_refused() -> None:
    """Still motion tells models nothing: a rigid model goes in (the rigid guard does not rely
    on it), a belt model does not (the belt guard does)."""
    e = Engine(SimDriver())
    run(e, 1.0)
    light = pan(**{"inertia.J": 0.2})
    check = e.check_model("pan", light)
    assert not check.judged and check.accepted and "held still" in check.note
    e.set_model("pan", light)
    belt = AxisModel.for_axis("pan", ["compliance"], BELT)
    with pytest.raises(ModelRefused, match="has a belt"):
        e.set_model("pan", belt)
    assert not e.model("pan").has("compliance")


def test_the_rigs_own_belt_is_accepted_and_a_belt_the_rig_lacks_is_refused() -> None:
    belt = AxisModel.for_axis("pan", ["compliance"], BELT)
    tilt = AxisModel.for_axis("tilt", ["quantization"])
    belt_rig = SimDriver({"pan": belt.with_effect("quantization"), "tilt": tilt})
    assert moved(belt_rig).check_model("pan", belt).accepted
    check = moved(SimDriver()).check_model("pan", belt)
    assert check.judged and not check.accepted, check.describe()
