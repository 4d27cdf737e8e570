"""The outside generator's own physics and logging convention (bench/outside_gen).

These check the generator against first principles, never the workbench: a held command moves
the axis first at the next row, the rigid-body equivalent it reports (K, viscous with back-EMF)
is the one its steady state obeys, its RK4 agrees with scipy's solve_ivp, an unforced axis only
loses energy, and its clean logs are written in the README's CSV format.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from bench.outside_gen import physics as ph
from bench.outside_gen.controllers import OpenLoop
from bench.outside_gen.generate import build, clearly_present, generate, size_of_effect
from bench.outside_gen.loop import Encoder, run_loop
from bench.outside_gen.plant import AxisPlant, Friction, Motor, Transmission

FINE = Encoder(16384, on_motor=True, rounding="round")


def _plant(law: str = "tanh", transmission: Transmission | None = None) -> AxisPlant:
    motor = Motor(
        r_ohm=6.0,
        l_h=1.5e-3,
        kt_nm_per_a=0.04,
        gear_ratio=6.3,
        amp_gain_v_per_v=2.0,
        amp_rail_v=1e3,
        j_rotor_kgm2=8e-6,
    )
    lugre = law == "lugre"
    fm = Friction(
        0.03, 0.03, 0.03, 0.02, 5e-4, 5e-4, 2e-4, 0.03 / 1e-4 if lugre else 0.0, 1.0 if lugre else 0.0, 0.05
    )
    fl = Friction(
        0.01, 0.01, 0.01, 0.02, 2e-4, 2e-4, 2e-4, 0.01 / 1e-4 if lugre else 0.0, 0.5 if lugre else 0.0, 0.05
    )
    return AxisPlant(
        motor=motor,
        j_load_kgm2=0.0025,
        law=law,
        friction_motor=fm,
        friction_load=fl,
        transmission=transmission or Transmission(),
    )


def _step_run(plant: AxisPlant, latency_ticks: int = 0, delay_s: float = 0.0, step_row: int = 10):
    u = np.zeros(40)
    u[step_row:] = 3.0
    return run_loop(plant, OpenLoop(u), 1e-3, 40, FINE, latency_ticks=latency_ticks, delay_s=delay_s)


@pytest.mark.parametrize("law", ["tanh", "lugre"])
def test_a_command_logged_at_row_i_first_moves_theta_at_row_i_plus_1(law: str) -> None:
    plant = _plant(law)
    run = _step_run(plant)
    assert np.all(run.motor_true_rad[:11] == 0.0)
    assert run.motor_true_rad[11] > 0.0  # positive volts, positive motion
    truth = plant.workbench_truth()
    held = 0.5 * truth["gain_nm_per_v"] * 3.0 / truth["inertia.J"] * 1e-3**2
    # the electrical lag (0.25 ms) and friction take some of it, nothing adds to it
    assert 0.3 * held < run.motor_true_rad[11] < held
    assert np.all(run.theta_rad[:11] == 0.0) and run.theta_rad[12] > 0.0


def test_latency_and_transport_delay_shift_the_first_motion() -> None:
    plant = _plant()
    late = _step_run(plant, latency_ticks=1)
    assert np.all(late.motor_true_rad[:12] == 0.0) and late.motor_true_rad[12] > 0.0
    delayed = _step_run(plant, delay_s=2.5e-3)  # applied from t = 12.5 ms
    assert np.all(delayed.motor_true_rad[:13] == 0.0) and delayed.motor_true_rad[13] > 0.0


@pytest.mark.parametrize("law", ["tanh", "lugre"])
def test_steady_speed_is_the_reported_rigid_equivalents(law: str) -> None:
    plant = _plant(law)
    truth = plant.workbench_truth()
    u_v = 2.0
    n = 3000
    run = run_loop(plant, OpenLoop(np.full(n, u_v)), 1e-3, n, FINE)
    speed = (run.motor_true_rad[-1] - run.motor_true_rad[-101]) / 0.1
    expected = (truth["gain_nm_per_v"] * u_v - truth["coulomb.torque"]) / truth["viscous.b"]
    assert speed == pytest.approx(expected, rel=0.01)
    # the back-EMF is most of the viscous term: a plant without it would run 3× faster
    assert plant.motor.back_emf_damping_nms_per_rad > 0.5 * truth["viscous.b"]


def test_rk4_agrees_with_solve_ivp_on_a_belt() -> None:
    plant = _plant("tanh", Transmission("belt", belt_hz=15.0, belt_damping=0.1))
    plant = replace(
        plant,
        friction_motor=replace(plant.friction_motor, tanh_eps_rad_s=0.05),
        friction_load=replace(plant.friction_load, tanh_eps_rad_s=0.05),
        gravity_nm=0.02,
        gravity_phase_rad=0.3,
    )
    p = plant.pack()
    x = np.zeros(ph.N_STATE)
    for _ in range(200):
        x = ph.advance(x, p, 1.5, 1.5, 0.0, 0.001, 0.001, 1e-3, ph.substeps_for(1e-3))
    ref = solve_ivp(
        lambda _t, y: ph.derivative(np.asarray(y), p, 1.5, 0.001),
        (0.0, 0.2),
        np.zeros(ph.N_STATE),
        method="Radau",
        rtol=1e-9,
        atol=1e-12,
    )
    assert ref.success
    np.testing.assert_allclose(x[1:5], ref.y[1:5, -1], atol=2e-7)


@pytest.mark.parametrize("kind", ["rigid", "belt"])
def test_an_unforced_axis_only_loses_energy(kind: str) -> None:
    plant = _plant("tanh", Transmission(kind, belt_hz=12.0, belt_damping=0.05))
    p = plant.pack()
    jm, jl = plant.j_motor_kgm2, plant.j_load_kgm2
    k_belt = p[ph.P_K_NM_RAD]

    def energy_j(x: np.ndarray) -> float:
        mech = (
            0.5 * (jm + jl) * x[2] ** 2
            if kind == "rigid"
            else (0.5 * jm * x[2] ** 2 + 0.5 * jl * x[4] ** 2 + 0.5 * k_belt * (x[1] - x[3]) ** 2)
        )
        return mech + 0.5 * plant.motor.l_h * x[0] ** 2

    x = np.zeros(ph.N_STATE)
    x[2] = x[4] = 3.0
    energies = [energy_j(x)]
    for _ in range(400):
        x = ph.advance(x, p, 0.0, 0.0, 0.0, 0.0, 0.0, 1e-3, ph.substeps_for(1e-3))
        energies.append(energy_j(x))
    assert np.all(np.diff(energies) <= 1e-12)
    assert energies[-1] < 0.01 * energies[0]
    assert x[1] > 0.0  # it coasted forward before stopping


def test_clean_logs_follow_the_csv_convention(tmp_path) -> None:  # type: ignore[no-untyped-def]
    for seed in (11, 12, 13):
        truth = generate(tmp_path, f"clean-{seed}", seed, None, duration_s=3.0)
        with open(tmp_path / f"clean-{seed}.csv") as fh:
            rows = list(csv.reader(fh))
        assert rows[0] == ["t", "u", "theta"]
        data = np.array(rows[1:], dtype=float)
        rate = truth["conditions"]["rate_hz"]  # type: ignore[index]
        assert data.shape == (int(3.0 * rate), 3)
        np.testing.assert_allclose(np.diff(data[:, 0]), 1.0 / rate, atol=2e-6)
        step = truth["size"]["encoder_step_rad"]  # type: ignore[index]
        counts = data[:, 2] / step
        np.testing.assert_allclose(counts, np.round(counts), atol=1e-4)
        assert np.ptp(counts) > 10  # the axis moved
        saved = json.loads((tmp_path / f"clean-{seed}.truth.json").read_text())
        assert saved["effect"] is None and saved["hidden_params"] == {}
        wb = saved["workbench_truth"]
        # no hidden effect: the amplifier's rail is never reached, no bias, no gravity, no cogging
        assert np.max(np.abs(data[:, 1])) < wb["saturation.limit"]
        assert wb["offset.torque"] == wb["gravity.torque"] == wb["ripple.amplitude"] == 0.0
        assert wb["stiction.static_torque"] <= 1.05 * wb["coulomb.torque"] + 1e-12
        motor = saved["plant"]["motor"]
        assert saved["gain_nm_per_v"] == pytest.approx(
            motor["gear_ratio"] * motor["kt_nm_per_a"] * motor["amp_gain_v_per_v"] / motor["r_ohm"]
        )
        assert math.isfinite(saved["conditions"]["electrical_tau_ms"])


def test_a_log_is_a_function_of_its_seed_and_its_effect_is_clearly_present() -> None:
    sc_a, run_a = build("offset-x", 5, "offset", duration_s=3.0)
    sc_b, run_b = build("offset-x", 5, "offset", duration_s=3.0)
    np.testing.assert_array_equal(run_a.theta_rad, run_b.theta_rad)
    np.testing.assert_array_equal(run_a.u_v, run_b.u_v)
    size = size_of_effect(sc_a, run_a)
    assert clearly_present(size)
    assert size["effect_torque_nm"] >= 3 * sc_a.disturbance_nm
    assert clearly_present({"effect_torque_nm": 1.0, "over_disturbance": 3.0, "over_count_torque": 1.5})
    assert not clearly_present({"effect_torque_nm": 1.0, "over_disturbance": 2.9, "over_count_torque": 9.0})
    assert not clearly_present({"width_counts": 5.0}) and not clearly_present({"twist_rms_counts": 2.0})
