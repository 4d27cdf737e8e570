"""Controller design: the seed's lead reproduced with python-control, ours beating it."""

import math

import control
import numpy as np
import pytest

from tracker.control.design import (
    SEED_PHASE_MARGIN_DEG,
    check_gains,
    design_controller,
    feedback_controller,
    plant_zoh,
)
from tracker.control.gains import LeadGains, ObserverPdGains
from tracker.errors import ConfigError
from tracker.plant.model import AxisModel

AXES = ["pan", "tilt"]


@pytest.mark.parametrize("axis", AXES)
def test_seed_lead_reproduces_the_reported_phase_margin_with_the_surviving_constants(axis: str) -> None:
    d = design_controller(AxisModel.for_axis(axis), "seed_lead", axis=axis)
    assert isinstance(d.gains, LeadGains)
    assert d.gains.pole == {"pan": 0.87, "tilt": 0.9}[axis]
    if axis == "tilt":
        assert d.gains.gain_v_per_rad == 141.0
    # A lead: the zero sits right of the pole, inside the unit circle.
    assert d.gains.pole < d.gains.zero < 1.0
    assert d.report.phase_margin_deg == pytest.approx(SEED_PHASE_MARGIN_DEG[axis], abs=0.05)
    assert d.report.stable


def test_margin_of_a_textbook_loop_matches_python_control_directly() -> None:
    """check_gains on a lead equals control.margin on the hand-built loop C(z)·P(z)."""
    m = AxisModel.for_axis("pan")
    g = LeadGains(200.0, 0.97, 0.87)
    loop = control.tf([200.0, -200.0 * 0.97], [1.0, -0.87], 1e-3) * plant_zoh(m)
    _, pm, _, _ = control.margin(loop)
    assert check_gains(m, g).phase_margin_deg == pytest.approx(pm, abs=0.05)


def test_observer_controller_matches_ideal_pd_at_low_frequency() -> None:
    """With a fast observer the feedback part is Kp + Kd·s well below the observer bandwidth."""
    m = AxisModel.for_axis("pan")
    g = ObserverPdGains(100.0, 2.0, 0.0, 200.0)
    c = feedback_controller(m, g)
    for f_hz in (0.5, 2.0, 8.0):
        w = 2 * math.pi * f_hz
        got = complex(c(np.exp(1j * w * 1e-3)))
        assert got == pytest.approx(100.0 + 2.0j * w, rel=0.03)


@pytest.mark.parametrize("axis", AXES)
def test_our_design_has_the_required_margins_even_with_a_sample_of_delay(axis: str) -> None:
    d = design_controller(AxisModel.for_axis(axis), "observer_pd_ff", axis=axis)
    assert d.report.stable and d.report_with_delay.stable
    assert d.report.phase_margin_deg >= 59.0
    assert d.report_with_delay.phase_margin_deg >= 45.0
    assert d.report.gain_margin_db >= 10.0


def test_check_gains_flags_an_unstable_loop() -> None:
    m = AxisModel.for_axis("pan")
    r = check_gains(m, ObserverPdGains(100.0, -2.0, 0.0, 50.0), min_phase_margin_deg=45.0)
    assert not r.stable and not r.ok


def test_unknown_controller_names_the_known_ones() -> None:
    with pytest.raises(ConfigError, match="observer_pd_ff"):
        design_controller(AxisModel.for_axis("pan"), "pid_magic")


@pytest.mark.parametrize(
    "gains",
    [
        LeadGains(200.0, 0.97, 0.87),
        ObserverPdGains(100.0, 2.0, 300.0, 60.0),
        ObserverPdGains(400.0, 0.2, 0.0, 40.0),
    ],
    ids=["lead", "pid-observer", "barely-stable"],
)
def test_fast_phase_margin_used_in_design_iterations_agrees_with_python_control(gains: object) -> None:
    from tracker.control.design import phase_margin_fast_deg

    m = AxisModel.for_axis("pan")
    assert phase_margin_fast_deg(m, gains) == pytest.approx(check_gains(m, gains).phase_margin_deg, abs=0.01)  # type: ignore[arg-type]
