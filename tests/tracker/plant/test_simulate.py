"""The simulator against physics: steady states, signs, stick-slip, effects one by one."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tracker.plant.model import AxisModel
from tracker.plant.simulate import initial_state, simulate

DT = 1e-3


def constant_voltage(volts: float, seconds: float, kick_s: float = 0.25) -> np.ndarray:
    """The seed's friction-ID input: a 10 V break-away pulse, then a constant voltage."""
    u = np.full(int(seconds / DT), volts)
    u[: int(kick_s / DT)] = 10.0 * math.copysign(1.0, volts)
    return u


def steady_speed(model: AxisModel, volts: float, seconds: float = 25.0) -> float:
    r = simulate(model, constant_voltage(volts, seconds), DT)
    return float(np.mean(r.omega_rad_s[-2000:]))


@pytest.mark.parametrize("volts", [0.9, -0.9, 1.5, -1.5], ids=lambda v: f"{v:+.1f}V")
def test_constant_voltage_settles_where_torque_balances_friction(volts: float) -> None:
    """K·V = b·ω + Fc·sign(ω) at steady state (seed section 3.1)."""
    m = AxisModel.for_axis("pan")
    k, b, fc = m.gain_nm_per_v, m.params["viscous.b"], m.params["coulomb.torque"]
    expected = (k * volts - math.copysign(fc, volts)) / b
    assert steady_speed(m, volts) == pytest.approx(expected, rel=0.01)


def test_axis_sticks_below_coulomb_torque_and_moves_above() -> None:
    m = AxisModel.for_axis("pan")
    below = 0.9 * m.params["coulomb.torque"] / m.gain_nm_per_v
    r = simulate(m, np.full(2000, below), DT)
    assert np.all(r.theta_rad == 0.0)
    r = simulate(m, np.full(2000, 1.2 * below / 0.9), DT)
    assert r.theta_rad[-1] > 0.0


def test_asymmetric_coulomb_changes_only_the_negative_direction() -> None:
    m = AxisModel.for_axis("pan", ["coulomb_asymmetry"], {"coulomb_asymmetry.negative": 0.07})
    k, b = m.gain_nm_per_v, m.params["viscous.b"]
    assert steady_speed(m, 1.5) == pytest.approx((k * 1.5 - 0.052) / b, rel=0.01)
    assert steady_speed(m, -1.5) == pytest.approx((-k * 1.5 + 0.07) / b, rel=0.01)


def test_asymmetric_viscous_changes_only_the_negative_slope() -> None:
    m = AxisModel.for_axis("pan", ["viscous_asymmetry"], {"viscous_asymmetry.negative": 1.3e-3})
    k, fc = m.gain_nm_per_v, m.params["coulomb.torque"]
    assert steady_speed(m, -1.5, 30.0) == pytest.approx((-k * 1.5 + fc) / 1.3e-3, rel=0.01)


def test_offset_torque_resists_positive_motion_and_helps_negative() -> None:
    m = AxisModel.for_axis("pan", ["offset"], {"offset.torque": 0.01})
    k, b, fc = m.gain_nm_per_v, m.params["viscous.b"], m.params["coulomb.torque"]
    assert steady_speed(m, 1.5) == pytest.approx((k * 1.5 - fc - 0.01) / b, rel=0.01)
    assert steady_speed(m, -1.5) == pytest.approx((-k * 1.5 + fc - 0.01) / b, rel=0.01)


def test_stiction_holds_above_coulomb_until_break_away() -> None:
    m = AxisModel.for_axis("pan", ["stiction"], {"stiction.static_torque": 0.08})
    between = 0.065 / m.gain_nm_per_v  # above Coulomb 0.052, below static 0.08
    assert np.all(simulate(m, np.full(2000, between), DT).theta_rad == 0.0)
    assert simulate(AxisModel.for_axis("pan"), np.full(2000, between), DT).theta_rad[-1] > 0


def test_gravity_holds_the_load_where_torque_balances_sin_theta() -> None:
    """With 0 V and no friction a pendulum-like unbalance swings around θ = −phase (stable side)."""
    m = AxisModel.for_axis(
        "tilt", ["gravity"], {"gravity.torque": 0.2, "coulomb.torque": 0.0, "viscous.b": 0.01}
    )
    r = simulate(m, np.zeros(20000), DT, x0=initial_state(0.5))
    assert abs(r.theta_rad[-1]) < 0.01
    # A constant voltage holds it where K·u = T·sin θ.
    u = 0.1 / m.gain_nm_per_v
    r = simulate(m, np.full(30000, u), DT)
    assert r.theta_rad[-1] == pytest.approx(math.asin(0.1 / 0.2), abs=0.01)


def test_delay_shifts_the_response_by_the_delay() -> None:
    u = np.zeros(3000)
    u[1000:] = 3.0
    base = simulate(AxisModel.for_axis("pan"), u, DT, quantize=False)
    late = simulate(AxisModel.for_axis("pan", ["delay"], {"delay.seconds": 0.0143}), u, DT, quantize=False)
    first_move = lambda r: int(np.flatnonzero(r.theta_rad > 0)[0])  # noqa: E731
    assert first_move(late) - first_move(base) in (14, 15)


def test_saturation_limits_the_torque() -> None:
    m = AxisModel.for_axis("pan", ["saturation"], {"saturation.limit": 2.0})
    sat = steady_speed(m, 5.0, 40.0)
    k, b, fc = m.gain_nm_per_v, m.params["viscous.b"], m.params["coulomb.torque"]
    assert sat == pytest.approx((k * 2.0 - fc) / b, rel=0.01)


def test_ripple_torque_makes_speed_periodic_in_theta_with_its_cycle_count() -> None:
    m = AxisModel.for_axis("pan", ["ripple"], {"ripple.amplitude": 0.01, "ripple.cycles_per_rev": 21})
    r = simulate(m, constant_voltage(1.2, 20.0), DT, quantize=False)
    th, w = r.theta_rad[8000:], r.omega_rad_s[8000:]
    # Project speed on sin/cos of 21θ: a strong component there, none at 17θ.
    amp = lambda n: abs(np.mean((w - w.mean()) * np.exp(-1j * n * th)))  # noqa: E731
    assert amp(21) > 10 * amp(17)


def test_backlash_lets_the_encoder_move_through_the_dead_band_before_the_load() -> None:
    m = AxisModel.for_axis("pan", ["backlash"], {"backlash.width": 0.02})
    u = np.concatenate([np.full(800, 2.0), np.full(400, -2.0)])
    r = simulate(m, u, DT, quantize=False)
    gap = r.theta_rad - r.load_theta_rad
    # Once driven, the motor leads the load by half the band (plus a small belt stretch) ...
    assert gap[799] == pytest.approx(0.01, abs=0.001)
    # ... and after the reversal it has crossed the whole band and leads the other way.
    assert gap[-1] == pytest.approx(-0.01, abs=0.001)
    assert abs(r.load_theta_rad[799] - r.theta_rad[799]) > 0.009


def test_compliance_rings_at_its_frequency() -> None:
    m = AxisModel.for_axis(
        "pan",
        ["compliance"],
        {"compliance.frequency": 12.0, "compliance.damping": 0.02, "coulomb.torque": 0.0},
    )
    u = np.zeros(4000)
    u[:20] = 5.0
    r = simulate(m, u, DT, quantize=False)
    twist = r.theta_rad[100:] - r.load_theta_rad[100:]
    spec = np.abs(np.fft.rfft(twist - twist.mean()))
    freqs = np.fft.rfftfreq(twist.size, DT)
    assert freqs[np.argmax(spec)] == pytest.approx(12.0, abs=0.5)


def test_quantization_reports_whole_counts() -> None:
    m = AxisModel.for_axis("pan", ["quantization"])
    r = simulate(m, constant_voltage(1.0, 2.0), DT)
    q = m.params["quantization.step"]
    assert np.allclose(r.theta_rad / q, np.round(r.theta_rad / q))


@settings(max_examples=30, deadline=None)
@given(volts=st.lists(st.floats(-12, 12), min_size=5, max_size=5))
def test_friction_never_reverses_motion_and_energy_stays_bounded(volts: list[float]) -> None:
    """Random piecewise-constant commands: speed never exceeds the free-run bound K·10V/b."""
    m = AxisModel.for_axis("pan", ["stiction", "coulomb_asymmetry"])
    u = np.repeat(np.asarray(volts), 300)
    r = simulate(m, u, DT)
    bound = m.gain_nm_per_v * 10.0 / m.params["viscous.b"]
    assert np.all(np.isfinite(r.theta_rad))
    assert np.max(np.abs(r.omega_rad_s)) <= bound


def test_a_command_beyond_the_rig_amplifier_is_delivered_and_a_saturation_still_clips() -> None:
    """Regression: the simulator clipped every command at the rig's ±10 V, so a log of a ±24 V
    drive commanding 16 V was simulated at 10 V. A given command is delivered as it is (its rail,
    ``drive_rail_v``, is never below it); only the saturation effect clips it."""
    m = AxisModel.for_axis("pan")
    k, b, fc = m.gain_nm_per_v, m.params["viscous.b"], m.params["coulomb.torque"]
    assert steady_speed(m, 16.0, 40.0) == pytest.approx((k * 16.0 - fc) / b, rel=0.01)
    clipped = AxisModel.for_axis("pan", ["saturation"], {"saturation.limit": 12.0})
    assert steady_speed(clipped, 16.0, 40.0) == pytest.approx((k * 12.0 - fc) / b, rel=0.01)


def test_the_rigs_twin_keeps_its_amplifiers_rail() -> None:
    """The closed loop and the simulated rig pack the plant without a rail: the rig's ±10 V."""
    from tracker.plant.effects.saturation import drive_rail_v
    from tracker.plant.simulate import I_ULIM, pack_params
    from tracker.units import AMPLIFIER_LIMIT_V

    m = AxisModel.for_axis("pan")
    assert pack_params(m, DT)[I_ULIM] == AMPLIFIER_LIMIT_V
    assert pack_params(m, DT, rail_v=drive_rail_v(np.array([3.0, -24.0])))[I_ULIM] == 24.0
    assert drive_rail_v(np.array([3.0, -7.0])) == AMPLIFIER_LIMIT_V  # a log within the rig's rail
    sat = AxisModel.for_axis("pan", ["saturation"], {"saturation.limit": 30.0})
    assert pack_params(sat, DT, rail_v=24.0)[I_ULIM] == 24.0  # above the rail it clips nothing more
