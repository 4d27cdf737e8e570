"""The simulated rig: config files, hidden effects, faults that latch, the fast path."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tracker.control.closed_loop import R_Y
from tracker.control.design import design_controller
from tracker.control.limits import SoftLimits
from tracker.control.loop import controller_step, new_state, pack_controller
from tracker.control.trajectory import DEFAULT_LIMITS
from tracker.drivers.motor import ClosedLoopDriver, MotorDriver
from tracker.drivers.sim import SimDriver, load_rig_config
from tracker.errors import ConfigError, DriverFault
from tracker.plant.model import AxisModel


def write(tmp_path: Path, cfg: object) -> Path:
    p = tmp_path / "rig.json"
    p.write_text(json.dumps(cfg))
    return p


def test_the_rig_is_a_motor_driver_with_a_fast_path() -> None:
    d = SimDriver()
    assert isinstance(d, MotorDriver) and isinstance(d, ClosedLoopDriver)
    assert d.models["pan"].has("quantization")


def test_config_hides_effects_that_show_up_in_measurements(tmp_path: Path) -> None:
    """Gravity the model lacks: with 0 V the loaded tilt axis falls, the nominal one stays."""
    cfg = {"tilt": {"effects": ["gravity"], "params": {"gravity.torque": 0.2, "gravity.phase": 0.5}}}
    hidden = SimDriver.from_config(write(tmp_path, cfg))
    plain = SimDriver()
    for d in (hidden, plain):
        d.enable()
        for _ in range(300):
            d.command("tilt", 0.0)
            d.tick()
    assert plain.read_encoder("tilt") == 0.0
    # τ = 0.2·sin(0.5) ≈ 0.096 N·m > Coulomb 0.0605: it moves, against the sine's sign.
    assert hidden.read_encoder("tilt") < -0.01


@pytest.mark.parametrize(
    ("cfg", "match"),
    [
        ({"roll": {}}, "unknown axis roll"),
        ({"pan": {"effects": ["warp"]}}, "pan.*unknown effect 'warp'"),
        ({"pan": {"effects": ["gravity"], "params": {"gravity.torque": -1}}}, "pan.*torque"),
        ({"pan": {"effects": "gravity"}}, "pan.effects must be a list"),
        ({"pan": {"params": {"offset.torque": 0.1}}}, "offset.torque.*does not have"),
    ],
    ids=["axis", "effect", "bound", "type", "param-without-effect"],
)
def test_bad_configs_are_refused_naming_the_problem(tmp_path: Path, cfg: object, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        load_rig_config(write(tmp_path, cfg))


def test_config_syntax_errors_name_the_file_and_line(tmp_path: Path) -> None:
    p = tmp_path / "rig.json"
    p.write_text('{\n "pan": {"effects": [,]}\n}')
    with pytest.raises(ConfigError, match=r"rig.json: line 2"):
        load_rig_config(p)


def test_a_fault_latches_disables_and_refuses_enable_until_cleared() -> None:
    d = SimDriver()
    d.enable()
    d.command("pan", float("nan"))
    assert not d.enabled and "pan" in d.faults()[0]
    with pytest.raises(DriverFault, match="latched"):
        d.enable()
    d.clear_faults()
    d.enable()
    assert d.enabled


def test_over_travel_past_the_end_stop_latches_a_fault() -> None:
    d = SimDriver()
    d.enable()
    for _ in range(3000):
        d.command("tilt", 10.0)  # no controller, no guard: straight into the stop
        d.tick()
        if d.faults():
            break
    assert d.faults() and "over-travel" in d.faults()[0]
    assert not d.enabled


def test_disabled_amplifier_applies_no_torque() -> None:
    d = SimDriver()
    for _ in range(200):
        d.command("pan", 10.0)
        d.tick()
    assert d.read_encoder("pan") == 0.0


def test_fast_path_equals_the_sample_by_sample_path() -> None:
    """The compiled chunk and the per-sample Protocol calls produce the same run."""
    axis = "pan"
    model = AxisModel.for_axis(axis)
    gains = design_controller(model, axis=axis).gains
    targets = np.full(500, math.radians(10.0))
    fast, slow = SimDriver(), SimDriver()
    fast.enable()
    slow.enable()

    def controller() -> tuple[np.ndarray, np.ndarray]:
        return pack_controller(
            model, gains, 1e-3, SoftLimits.for_axis(axis), DEFAULT_LIMITS[axis]
        ), new_state()

    cp, cs = controller()
    rec = fast.run_closed_loop(axis, cp, cs, targets)
    cp2, cs2 = controller()
    ys = []
    for r in targets:
        y = slow.read_encoder(axis)
        ys.append(y)
        slow.command(axis, controller_step(cp2, cs2, y, float(r)))
        slow.tick()
    np.testing.assert_allclose(rec[:, R_Y], ys, atol=1e-12)
    assert fast.load_angle_rad(axis) == pytest.approx(slow.load_angle_rad(axis), abs=1e-12)
