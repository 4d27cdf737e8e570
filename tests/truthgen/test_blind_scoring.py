"""The blind matrix's parameter score compares like with like (bench/blind_matrix.py).

The truth generator records physical values; the log shows two of them in its own conventions:
the lag from a logged command to the motor includes the controller's computational latency, and
a truncating encoder shifts every logged angle by half a count. These tests check the score's
translation against logs simulated by the generator itself, so a wrong translation fails here.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from tests.truthgen.axis import TrueAxis
from tests.truthgen.presets import GAIN_NM_PER_V, PAN
from tests.truthgen.run import replay

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
import blind_matrix as bm  # noqa: E402


def _truth(**kw: object) -> dict[str, object]:
    t: dict[str, object] = {
        "params": {"inertia.J": 1e-3, "quantization.step": 0.01},
        "latency_samples": 0,
        "sample_rate_hz": 500,
        "encoder_mode": "round",
        "hidden": [],
    }
    t.update(kw)
    return t


def test_delay_as_the_log_sees_it_includes_the_computational_latency() -> None:
    t = _truth(params={"delay.seconds": 0.004}, latency_samples=1, hidden=["delay"])
    assert bm.seen_by_log(t)["delay.seconds"] == 0.004 + 1 / 500
    assert bm.seen_by_log({**t, "latency_samples": 0})["delay.seconds"] == 0.004
    assert bm.fit_effects(t) == ["delay"]


def test_a_latency_alone_is_fitted_as_a_one_sample_delay_and_scored_apart() -> None:
    t = _truth(params={"gravity.torque": 0.05, "gravity.phase": 0.3}, latency_samples=1, hidden=["gravity"])
    assert bm.fit_effects(t) == ["gravity", "delay"]
    assert bm.seen_by_log(t)["delay.seconds"] == 1 / 500
    assert bm.fit_effects({**t, "latency_samples": 0}) == ["gravity"]


def test_phases_of_a_truncating_encoder_are_shifted_by_half_a_count_per_cycle() -> None:
    q, n, phi = 0.01, 30.0, 3.0
    t = _truth(
        params={
            "quantization.step": q,
            "ripple.cycles_per_rev": n,
            "ripple.phase": phi,
            "gravity.phase": -0.2,
        },
        encoder_mode="truncate",
        hidden=["ripple", "gravity"],
    )
    seen = bm.seen_by_log(t)
    assert math.isclose(seen["ripple.phase"], math.remainder(phi + n * q / 2, 2 * math.pi))
    assert math.isclose(seen["gravity.phase"], -0.2 + q / 2)
    rounded = bm.seen_by_log({**t, "encoder_mode": "round"})
    assert math.isclose(rounded["ripple.phase"], phi) and math.isclose(rounded["gravity.phase"], -0.2)


def test_the_logged_lag_is_latency_plus_delay_on_a_simulated_log() -> None:
    """Replay one command step through the generator: the first logged motion comes exactly
    ``seen_by_log``'s delay after the logged step (rounded up to the next sample)."""
    rate = 1000.0
    p = {
        "inertia.J": PAN.inertia,
        "viscous.b": PAN.viscous,
        "coulomb.torque": 0.0,
        "inertia.motor_fraction": 0.15,
        "quantization.step": 0.0,
        "delay.seconds": 0.0032,
    }
    u = np.zeros(40)
    u[10:] = 2.0
    for latency in (0, 1):
        axis = TrueAxis(GAIN_NM_PER_V, dict(p), ["delay"])
        log = replay(axis, u, rate, latency_samples=latency)
        moved = int(np.flatnonzero(np.abs(log.theta) > 0)[0])
        lag = bm.seen_by_log(_truth(params=p, latency_samples=latency, sample_rate_hz=rate))["delay.seconds"]
        # the command logged on row 10 is applied from t_10 + lag: theta moves first on the next row
        assert moved == 10 + math.floor(lag * rate) + 1


def test_truncating_encoder_reads_half_a_count_low_on_average() -> None:
    """The premise of the phase translation: floor(θ/q)·q averages θ − q/2."""
    from tests.truthgen.encoder import ENC_TRUNC, quantize

    q = 0.01
    th = np.random.default_rng(1).uniform(-1, 1, 20000)
    got = np.array([quantize(x, q, ENC_TRUNC) for x in th])
    assert abs(float(np.mean(th - got)) - q / 2) < 1e-4


def test_param_error_units() -> None:
    assert bm._param_error("delay.seconds", 0.0105, 0.01)["ok"] == 1.0
    assert bm._param_error("delay.seconds", 0.0115, 0.01)["ok"] == 0.0
    assert bm._param_error("ripple.phase", math.pi - 0.05, -math.pi + 0.04)["ok"] == 1.0
    assert bm._param_error("viscous.b", 1.11, 1.0)["ok"] == 0.0
