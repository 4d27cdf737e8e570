"""The simulator's generic path: a torque of the angle read from a table, against the built-in path."""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np
import pytest

from tracker.plant.effects import Effect, FloatArray, Param, register_effect, unregister_effect
from tracker.plant.model import AxisModel
from tracker.plant.simulate import I_TABN, N_PACKED, initial_state, pack_params, simulate

DT = 1e-3


def _gravity_again(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    return params["grav_table.torque"] * np.sin(np.asarray(theta, dtype=float) + params["grav_table.phase"])


def _ripple_again(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    th = np.asarray(theta, dtype=float)
    return params["ripple_table.amplitude"] * np.sin(3.0 * th + params["ripple_table.phase"])


GRAVITY_AGAIN = Effect(
    name="grav_table",
    kind="torque",
    description="gravity, written as a site's own effect",
    params=(
        Param("torque", "N·m", 0.0, 0.0, 10.0, "unbalance torque amplitude"),
        Param("phase", "rad", 0.0, -np.pi, np.pi, "angle offset"),
    ),
    signature="residual torque follows sin θ",
    torque_nm=_gravity_again,
    search={"phase": tuple(np.linspace(-3.0, 3.0, 7))},
)
RIPPLE_AGAIN = Effect(
    name="ripple_table",
    kind="torque",
    description="a 3-cycle ripple, written as a site's own effect",
    params=(
        Param("amplitude", "N·m", 0.0, 0.0, 10.0, "ripple amplitude"),
        Param("phase", "rad", 0.0, -np.pi, np.pi, "phase"),
    ),
    signature="residual is periodic in θ",
    torque_nm=_ripple_again,
)


@pytest.fixture(scope="module", autouse=True)
def _registered() -> Iterator[None]:
    register_effect(GRAVITY_AGAIN)
    register_effect(RIPPLE_AGAIN)
    yield
    unregister_effect("grav_table")
    unregister_effect("ripple_table")


def _command(seconds: float, seed: int) -> FloatArray:
    """Random 50 ms steps of ±2 V: moves, reversals and holds (stick) over about ±2 rad."""
    rng = np.random.default_rng(seed)
    return np.repeat(np.clip(rng.normal(0.0, 1.5, int(seconds / 0.05)), -4.0, 4.0), int(0.05 / DT))


def test_without_generic_effects_the_packed_vector_has_no_table() -> None:
    P = pack_params(AxisModel.for_axis("pan", ["gravity", "ripple"]), DT)
    assert P.shape == (N_PACKED,) and P[I_TABN] == 0.0


@pytest.mark.parametrize("start_rad", [0.0, 3.0], ids=["from-zero", "from-3-rad"])
def test_gravity_as_a_table_follows_the_built_in_gravity(start_rad: float) -> None:
    values = {"torque": 0.05, "phase": 0.7}
    builtin = AxisModel.for_axis("pan", ["gravity"], {f"gravity.{k}": v for k, v in values.items()})
    table = AxisModel.for_axis("pan", ["grav_table"], {f"grav_table.{k}": v for k, v in values.items()})
    u = _command(10.0, 3)
    a = simulate(builtin, u, DT, initial_state(start_rad))
    b = simulate(table, u, DT, initial_state(start_rad))
    assert np.ptp(a.theta_rad) > 1.0  # it moved through much of a sine period
    assert np.max(np.abs(a.theta_rad - b.theta_rad)) < 2e-6  # rad, over 10 s with stick-slip
    assert np.max(np.abs(a.omega_rad_s - b.omega_rad_s)) < 1e-5


def test_a_tabulated_torque_acts_on_the_motor_side_of_a_belt() -> None:
    # Ripple is a motor-side torque in the built-in two-mass model, like the table.
    belt = {"compliance.frequency": 15.0, "compliance.damping": 0.1}
    builtin = AxisModel.for_axis(
        "pan",
        ["compliance", "ripple"],
        {**belt, "ripple.amplitude": 0.01, "ripple.cycles_per_rev": 3.0, "ripple.phase": 0.3},
    )
    table = AxisModel.for_axis(
        "pan",
        ["compliance", "ripple_table"],
        {**belt, "ripple_table.amplitude": 0.01, "ripple_table.phase": 0.3},
    )
    u = _command(6.0, 4)
    a, b = simulate(builtin, u, DT), simulate(table, u, DT)
    assert np.max(np.abs(a.theta_rad - b.theta_rad)) < 2e-6
    assert np.max(np.abs(a.load_theta_rad - b.load_theta_rad)) < 2e-6
