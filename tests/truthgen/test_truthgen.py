"""Tests of the independent truth generator: physics against closed forms, convergence, log convention."""

from __future__ import annotations

import ast
import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.truthgen import plant as pl
from tests.truthgen.axis import TrueAxis
from tests.truthgen.csvio import log_csv, read_csv, write_case
from tests.truthgen.loop import new_state
from tests.truthgen.matrix import (
    PAIRS,
    SAMPLE_CASE_IDS,
    build_matrix,
    case_spec,
    check_log,
    draw_effect,
    generate_case,
)
from tests.truthgen.presets import EFFECTS, GAIN_NM_PER_V, PAN
from tests.truthgen.run import replay

ROOT = Path(__file__).resolve().parents[2]
K = GAIN_NM_PER_V
J, B, FC = PAN.inertia, PAN.viscous, PAN.coulomb


def make_axis(
    hidden: tuple[str, ...] = (),
    law: str = "karnopp",
    friction: dict[str, float] | None = None,
    **params: float,
) -> TrueAxis:
    p = {
        "inertia.J": J,
        "viscous.b": B,
        "coulomb.torque": FC,
        "inertia.motor_fraction": 0.15,
        "quantization.step": 0.0,
    }
    p.update({k.replace("__", "."): v for k, v in params.items()})
    return TrueAxis(K, p, list(hidden), law, friction or {})


def moving_state(omega: float) -> np.ndarray:
    x = new_state()
    x[pl.STUCK] = 0.0
    x[pl.OM_M] = x[pl.OM_L] = omega
    x[pl.DIR] = math.copysign(1.0, omega)
    return x


# ------------------------------------------------------------------------------ independence


def test_generator_imports_nothing_from_tracker() -> None:
    code = (
        "import sys, numpy as np\n"
        f"sys.path.insert(0, {str(ROOT)!r})\n"
        "import tests.truthgen.matrix, tests.truthgen.csvio\n"
        "from tests.truthgen.axis import TrueAxis\n"
        "from tests.truthgen.run import replay\n"
        "p = {'inertia.J': 0.003, 'viscous.b': 8e-4, 'coulomb.torque': 0.05, 'inertia.motor_fraction': 0.15,"
        " 'quantization.step': 3e-4}\n"
        "u = np.zeros(500); u[50:80] = 3.0; u[200:230] = -3.0\n"
        "log = replay(TrueAxis(0.074, p, []), u, 1000.0)\n"
        "assert np.ptp(log.theta) > 0\n"
        "bad = [m for m in sys.modules if m == 'tracker' or m.startswith('tracker.')]\n"
        "assert not bad, bad\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd="/")
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
    # and no module of the package even names tracker in an import
    for f in (ROOT / "tests" / "truthgen").glob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom):
                assert not (node.module or "").startswith("tracker"), f
            elif isinstance(node, ast.Import):
                assert not any(a.name.startswith("tracker") for a in node.names), f


# ----------------------------------------------------------------------------------- physics


def test_free_deceleration_stops_at_the_analytic_time_and_angle() -> None:
    w0, rate = 3.0, 1000.0
    ax = make_axis()
    log = replay(ax, np.zeros(600), rate, x0=moving_state(w0))
    tau = J / B
    t_stop = tau * math.log(1.0 + B * w0 / FC)
    th_stop = tau * w0 - FC * t_stop / B
    t = log.t
    moving = t < t_stop
    th = tau * (w0 + FC / B) * (1.0 - np.exp(-t / tau)) - FC * t / B
    assert np.max(np.abs(log.theta[moving] - th[moving])) < 1e-10
    assert np.max(np.abs(log.theta[~moving] - th_stop)) < 1e-10  # stopped there, and stays
    # stop time: the last moving tick and the first stopped one bracket t_stop
    assert 0.1 < t_stop < 0.5


def test_torque_below_breakaway_keeps_the_axis_stuck() -> None:
    n = 2000
    # Karnopp: 0.95 Fc holds
    log = replay(make_axis(), np.full(n, 0.95 * FC / K), 1000.0)
    assert np.all(log.theta == 0.0)
    # stiction: above Fc but below Fs holds, above Fs breaks away
    fs = 2.0 * FC
    ax = make_axis(("stiction",), stiction__static_torque=fs, stiction__velocity=0.03)
    assert np.all(replay(ax, np.full(n, 1.5 * FC / K), 1000.0).theta == 0.0)
    assert replay(ax, np.full(n, 1.02 * fs / K), 1000.0).theta[-1] > 0.1
    # coulomb asymmetry: the negative break-away is coulomb_asymmetry.negative
    ax = make_axis(("coulomb_asymmetry",), coulomb_asymmetry__negative=1.5 * FC)
    assert np.all(replay(ax, np.full(n, -1.3 * FC / K), 1000.0).theta == 0.0)
    assert replay(ax, np.full(n, -1.6 * FC / K), 1000.0).theta[-1] < -0.01


def test_linear_open_loop_step_matches_the_analytic_solution() -> None:
    q = 2 * math.pi / 20000  # the finest encoder count of the matrix
    for rate in (250.0, 2000.0):
        ax = make_axis(coulomb__torque=0.0)
        u = np.zeros(int(rate))
        i0 = 7
        u[i0:] = 1.5
        log = replay(ax, u, rate)
        t = np.clip(log.t - i0 / rate, 0.0, None)
        th = (K * 1.5 / B) * (t - J / B * (1.0 - np.exp(-B * t / J)))
        assert np.max(np.abs(log.theta - th)) < 1e-4 * q


def test_gravity_equilibrium_angle_under_constant_torque() -> None:
    tg, ph, tq = 0.06, 0.4, 0.03
    ax = make_axis(("gravity",), coulomb__torque=0.0, viscous__b=0.02, gravity__torque=tg, gravity__phase=ph)
    log = replay(ax, np.full(10000, tq / K), 1000.0)
    eq = math.asin(tq / tg) - ph
    assert abs(log.theta[-1] - eq) < 1e-6
    # with the offset (a resisting torque) the equilibrium moves by asin
    ax.params["offset.torque"] = 0.01
    ax.hidden.append("offset")
    log = replay(ax, np.full(10000, tq / K), 1000.0)
    assert abs(log.theta[-1] - (math.asin((tq - 0.01) / tg) - ph)) < 1e-6


@pytest.mark.parametrize("freq", [8.0, 30.0])
def test_two_mass_free_oscillation_frequency(freq: float) -> None:
    zeta = 0.01
    ax = make_axis(
        ("compliance",),
        coulomb__torque=0.0,
        viscous__b=0.0,
        compliance__frequency=freq,
        compliance__damping=zeta,
    )
    rate = 2000.0
    x = moving_state(0.0)
    x[pl.OM_M] = x[pl.OM_L] = 0.0
    x[pl.TH_M] = 0.01  # an initial twist, released
    log = replay(ax, np.zeros(int(2.0 * rate)), rate, x0=x)
    twist = log.theta_motor - log.theta_load
    s = np.sign(twist)
    idx = np.nonzero(np.diff(s) != 0)[0]
    # interpolated crossing times
    tc = log.t[idx] + (log.t[idx + 1] - log.t[idx]) * twist[idx] / (twist[idx] - twist[idx + 1])
    f_meas = (len(tc) - 1) / 2.0 / (tc[-1] - tc[0])
    assert abs(f_meas / (freq * math.sqrt(1 - zeta**2)) - 1.0) < 0.02
    assert abs(f_meas / (freq * math.sqrt(1 - zeta**2)) - 1.0) < 0.002  # in fact much closer
    # the centre of mass does not move (no external torque)
    com = 0.15 * log.theta_motor + 0.85 * log.theta_load
    assert np.max(np.abs(com - com[0])) < 1e-9


def _pulses(n: int, rng: np.random.Generator) -> np.ndarray:
    u = np.zeros(n)
    i = 20
    while i < n:
        k = int(rng.integers(20, 120))
        u[i : i + k] = rng.choice([-1, 1]) * rng.uniform(1.0, 3.0)
        i += k + int(rng.integers(50, 300))
    return u


def test_delay_shifts_the_response_by_exactly_d() -> None:
    rate = 1000.0
    # linear plant, fractional delay: analytic
    d = 0.0073
    ax = make_axis(("delay",), coulomb__torque=0.0, delay__seconds=d)
    u = np.zeros(100)
    u[10:] = 2.0
    log = replay(ax, u, rate)
    t = np.clip(log.t - 10 / rate - d, 0.0, None)
    th = (K * 2.0 / B) * (t - J / B * (1.0 - np.exp(-B * t / J)))
    assert np.max(np.abs(log.theta - th)) < 1e-12
    # nonlinear plant (stiction, ripple, gravity): a delay of 3 samples is a shift by 3 rows
    rng = np.random.default_rng(3)
    extra: dict[str, Any] = dict(
        stiction__static_torque=1.8 * FC,
        stiction__velocity=0.04,
        ripple__amplitude=0.015,
        ripple__cycles_per_rev=23.5,
        ripple__phase=0.3,
        gravity__torque=0.03,
        gravity__phase=1.0,
    )
    u = _pulses(3000, rng)
    base = replay(make_axis(("stiction", "ripple", "gravity"), **extra), u, rate)
    late = replay(
        make_axis(("stiction", "ripple", "gravity", "delay"), delay__seconds=3 / rate, **extra), u, rate
    )
    assert np.max(np.abs(late.theta[3:] - base.theta[:-3])) < 1e-12
    assert np.all(late.theta[:3] == 0.0)
    # latency 1 + 2.5 samples of delay is the same as 3.5 samples of delay
    a = replay(make_axis(("delay",), delay__seconds=2.5 / rate), u, rate, latency_samples=1)
    b = replay(make_axis(("delay",), delay__seconds=3.5 / rate), u, rate)
    assert np.max(np.abs(a.theta - b.theta)) < 1e-12


@pytest.mark.parametrize(
    "case_id", ["clean-000", "clean-004", "stiction-003", "compliance-000", "backlash-000"]
)
def test_convergence_under_step_halving(case_id: str) -> None:
    """Whole closed-loop logs (Karnopp, LuGre, stiction, belt, backlash) with h and h/2."""
    a, truth = generate_case(case_id)
    b, truth2 = generate_case(case_id, refine=2.0)
    assert truth2["attempt"] == truth["attempt"]
    q = truth["params"]["quantization.step"]
    assert np.ptp(a.theta_motor) > 0.1
    assert np.max(np.abs(a.theta_motor - b.theta_motor)) < 1e-4 * q  # the true angle
    assert np.array_equal(a.theta, b.theta)  # the logged angle: not one count changes
    assert np.array_equal(a.u, b.u)


def test_sub_count_chaos_is_physics_not_integration_error() -> None:
    """Some logs (stick-slip with a Stribeck dip, backlash chatter, ripple's negative stiffness)
    amplify any sub-count difference until a count flips: there halving h changes the log about
    as much as changing J by one part in 10¹³ does, i.e. the integrator is at round-off level."""
    import tests.truthgen.matrix as M

    cid = "stiction-001"
    a, truth = M.generate_case(cid)
    b, _ = M.generate_case(cid, refine=2.0)
    orig = M.draw_axis

    def nudged(spec: M.CaseSpec, rng: np.random.Generator) -> TrueAxis:
        ax = orig(spec, rng)
        ax.params["inertia.J"] *= 1.0 + 1e-13
        return ax

    M.draw_axis = nudged
    try:
        c, _ = M.generate_case(cid)
    finally:
        M.draw_axis = orig
    q = truth["params"]["quantization.step"]
    d_h = np.max(np.abs(a.theta - b.theta)) / q
    d_j = np.max(np.abs(a.theta - c.theta)) / q
    assert d_j >= 1.0  # the trajectory is sensitive at the count level ...
    assert d_h <= 5.0  # ... and h/2 does no worse than a few counts somewhere in 30 s
    n = int(5.0 * truth["sample_rate_hz"])
    assert np.max(np.abs(a.theta_motor[:n] - b.theta_motor[:n])) < 1e-6 * q  # before it sets in


def test_lugre_clean_has_the_coulomb_viscous_steady_state_and_presliding() -> None:
    b = 0.01
    s0 = FC / 2e-4
    fr = {"sigma0": s0, "sigma1": 2 * 0.5 * math.sqrt(s0 * J), "static_torque": FC, "velocity": 0.05}
    lug = make_axis(law="lugre", friction=fr, viscous__b=b)
    kar = make_axis(viscous__b=b)
    u = np.full(4000, 2.0 * FC / K)
    w_l = np.diff(replay(lug, u, 1000.0).theta)[-1] * 1000.0
    w_k = np.diff(replay(kar, u, 1000.0).theta)[-1] * 1000.0
    assert abs(w_l / (FC / b) - 1) < 1e-3 and abs(w_k / (FC / b) - 1) < 1e-3
    # below Fc: a micro-displacement of the order of Fc/σ0, and no sliding
    th = replay(lug, np.full(3000, 0.5 * FC / K), 1000.0).theta
    assert 0.3 * 0.5 * FC / s0 < th[-1] < 3.0 * FC / s0
    assert abs(th[-1] - th[-1000]) < 1e-3 * FC / s0


# ------------------------------------------------------------------------------- convention


@pytest.mark.parametrize("latency", [0, 1])
def test_step_logged_at_row_i_first_moves_the_angle_at_row_i_plus_1_plus_latency(latency: int) -> None:
    i = 40
    u = np.zeros(80)
    u[i:] = 8.0
    # unquantized at 1 kHz, and a 20000-count encoder at 250 Hz
    for rate, q in ((1000.0, 0.0), (250.0, 2 * math.pi / 20000)):
        ax = make_axis(quantization__step=q)
        th = replay(ax, u, rate, latency_samples=latency).theta
        first = int(np.nonzero(th != th[0])[0][0])
        assert first == i + 1 + latency, (rate, first)


# ------------------------------------------------------------------------------------ matrix


def test_matrix_layout() -> None:
    cases = build_matrix()
    ids = [c.id for c in cases]
    assert len(cases) >= 220 and len(set(ids)) == len(ids)
    groups = {g: [c for c in cases if c.group == g] for g in ("clean", "single", "pair")}
    assert len(groups["clean"]) >= 50 and len(groups["single"]) >= 110 and len(groups["pair"]) >= 60
    assert {c.hidden[0] for c in groups["single"]} == set(EFFECTS)
    assert ("backlash", "compliance") not in PAIRS and ("compliance", "backlash") not in PAIRS
    for lab in {"+".join(c.hidden) or "clean" for c in cases}:
        splits = {c.split for c in cases if ("+".join(c.hidden) or "clean") == lab}
        assert splits == {"dev", "heldout"}, lab
    clean = groups["clean"]
    for law in ("karnopp", "stribeck", "lugre"):
        for lat in (0, 1):
            sel = [c for c in clean if c.friction_law == law and c.latency_samples == lat]
            assert {c.split for c in sel} == {"dev", "heldout"}, (law, lat)
    assert {c.rate_hz for c in cases} == {250, 500, 1000, 2000}
    assert {c.axis for c in cases} == {"pan", "tilt"}
    # physical-delay draws are at least two samples
    rng = np.random.default_rng(0)
    for c in cases:
        if "delay" in c.hidden:
            d = draw_effect("delay", rng, {"coulomb.torque": FC, "viscous.b": B}, c)["delay.seconds"]
            assert 2.0 / c.rate_hz <= d <= 0.020


def test_sample_cases_are_good_logs_with_a_full_truth(tmp_path: Path) -> None:
    want: dict[str, tuple[int, int, list[str]]] = {"clean-000": (1000, 0, []), "clean-002": (500, 0, [])}
    for cid in SAMPLE_CASE_IDS:
        log, truth = generate_case(cid)
        spec = case_spec(cid)
        assert truth["id"] == cid and truth["split"] == "dev"
        for key in (
            "axis",
            "gain_nm_per_v",
            "sample_rate_hz",
            "encoder_counts_per_rev",
            "encoder_mode",
            "latency_samples",
            "controller",
            "friction_law",
            "hidden",
            "params",
            "noise",
        ):
            assert key in truth
        p = truth["params"]
        for key in (
            "inertia.J",
            "viscous.b",
            "coulomb.torque",
            "inertia.motor_fraction",
            "quantization.step",
        ):
            assert key in p
        assert truth["gain_nm_per_v"] == pytest.approx(0.0741636)
        assert p["quantization.step"] == pytest.approx(2 * math.pi / truth["encoder_counts_per_rev"])
        if cid in want:
            assert (truth["sample_rate_hz"], truth["latency_samples"], truth["hidden"]) == want[cid]
        assert truth["hidden"] == list(spec.hidden)
        rate = truth["sample_rate_hz"]
        assert len(log.t) == 30 * rate and log.t[0] == 0.0 and log.t[1] == pytest.approx(1.0 / rate)
        assert check_log(log, spec, TrueAxis(truth["gain_nm_per_v"], p, truth["hidden"])) == []
        assert np.max(np.abs(log.u)) <= 10.0
        q = p["quantization.step"]
        assert (
            np.allclose(log.theta / q, np.round(log.theta / q), atol=1e-6)
            or truth["noise"]["theta_std_rad"] > 0
        )
    assert generate_case("clean-000")[1]["friction_law"] == "karnopp"
    rp = generate_case("ripple-001")[1]["params"]["ripple.cycles_per_rev"]
    assert rp != round(rp)
    assert generate_case("delay-001")[1]["params"]["delay.seconds"] >= 0.003
    # deterministic, and the CSV round-trips at full precision
    log, truth = generate_case("gravity-000")
    log2, truth2 = generate_case("gravity-000")
    assert np.array_equal(log.theta, log2.theta) and truth == truth2
    path = write_case(tmp_path, log, truth)
    assert path == tmp_path / "dev" / "gravity-000.csv"
    assert log_csv(log).splitlines()[0] == "t,u,theta"
    t, u, th = read_csv(path)
    assert np.array_equal(t, log.t) and np.array_equal(u, log.u) and np.array_equal(th, log.theta)
    assert json.loads(path.with_suffix(".json").read_text())["params"] == truth["params"]


def test_check_log_rejects_a_log_that_does_not_move() -> None:
    from tests.truthgen.run import Log

    spec = case_spec("clean-000")
    n = 30 * spec.rate_hz
    t = np.arange(n) / spec.rate_hz
    still = Log(t, np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n))
    problems = check_log(still, spec, make_axis())
    assert any("span" in p for p in problems) and any("moving" in p for p in problems)
    wild = 5.0 * np.sin(2 * np.pi * 3.0 * t)  # too fast and off the range
    assert any("speed" in p for p in check_log(Log(t, np.zeros(n), wild, wild, wild), spec, make_axis()))
