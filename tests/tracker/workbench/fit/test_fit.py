"""The fitter recovers known parameters from closed-loop runs of the twin (physical ground truth)."""

import math

import numpy as np
import pytest

from tracker.errors import ConfigError, JobCancelled
from tracker.plant.model import AxisModel
from tracker.workbench.experiments.excite import closed_loop_log
from tracker.workbench.fit.fit import fit_model

# Hidden effects at physical values; the fit starts from the seed preset with base values off by 25-40 %.
CASES = {
    "offset": {"offset.torque": 0.012},
    "gravity": {"gravity.torque": 0.06, "gravity.phase": 0.5},
    "coulomb_asymmetry": {"coulomb_asymmetry.negative": 0.075},
    "viscous_asymmetry": {"viscous_asymmetry.negative": 2.5e-3},
    "stiction": {"stiction.static_torque": 0.085, "stiction.velocity": 0.08},
    "delay": {"delay.seconds": 0.014},
    "saturation": {"saturation.limit": 3.0},
    "ripple": {"ripple.amplitude": 0.012, "ripple.cycles_per_rev": 21.0, "ripple.phase": -0.7},
    "compliance": {"compliance.frequency": 15.0, "compliance.damping": 0.1},
    "backlash": {"backlash.width": 0.01},
}
PERTURBED = {"inertia.J": 1.25, "viscous.b": 0.7, "coulomb.torque": 1.35}


def _start(effects: tuple[str, ...]) -> AxisModel:
    pan = AxisModel.for_axis("pan", effects)
    return pan.with_params({k: pan.params[k] * f for k, f in PERTURBED.items()})


def _assert_close(name: str, got: float, want: float) -> None:
    if name.endswith(".phase"):
        assert abs(math.remainder(got - want, 2 * math.pi)) < 0.1, f"{name}: {got:.4g} vs {want:.4g} rad"
    else:
        assert got == pytest.approx(want, rel=0.10), f"{name}: {got:.4g} vs {want:.4g}"


@pytest.mark.parametrize("effect", [e for e in CASES if e != "backlash"])
def test_fit_recovers_each_effects_parameters_within_10_percent(effect: str) -> None:
    true = AxisModel.for_axis("pan", ["quantization", effect], CASES[effect])
    meas = closed_loop_log(true, duration_s=30.0, seed=11, disturbance_nm=0.0005)
    res = fit_model(meas, _start((effect,)))
    for name in CASES[effect]:
        if name == "ripple.cycles_per_rev":
            # searched on the spectrum, then fitted as a real number with the rest
            assert res.params[name] == pytest.approx(21.0, abs=0.1)
            continue
        _assert_close(name, res.params[name], true.params[name])
    for name in ("inertia.J", "coulomb.torque"):
        _assert_close(name, res.params[name], true.params[name])
    assert res.converged
    assert set(res.stderr) >= {k for k in CASES[effect] if k != "ripple.cycles_per_rev"}
    # A saturation's limit is bounded by the log's drive rail (the twin's ±10 V amplifier here).
    assert res.upper_bounds == ({"saturation.limit": 10.0} if effect == "saturation" else {})


@pytest.mark.parametrize("width_rad", [0.005, 0.02])
def test_backlash_width_recovered_within_15_percent(width_rad: float) -> None:
    """Backlash misses the 10 % aim on some runs: while the motor holds, the frictionless load
    coasts through the gap unobserved, so the cost is flat and noisy near the true width
    (9 runs of bench-like data: errors −13 % … +11 %, mean |error| 7 %)."""
    true = AxisModel.for_axis("pan", ["quantization", "backlash"], {"backlash.width": width_rad})
    meas = closed_loop_log(true, duration_s=30.0, seed=11, disturbance_nm=0.0005)
    res = fit_model(meas, _start(("backlash",)))
    assert res.params["backlash.width"] == pytest.approx(width_rad, rel=0.15)
    for name in ("inertia.J", "coulomb.torque"):
        _assert_close(name, res.params[name], true.params[name])


def test_base_model_recovered_from_a_start_far_off() -> None:
    true = AxisModel.for_axis("pan", ["quantization"])
    meas = closed_loop_log(true, duration_s=30.0, seed=5, disturbance_nm=0.0)
    res = fit_model(meas, _start(()))
    for name in ("inertia.J", "viscous.b", "coulomb.torque"):
        _assert_close(name, res.params[name], true.params[name])
    assert res.fit_percent > 99.0


def test_standard_errors_cover_the_truth_and_shrink_with_more_data() -> None:
    true = AxisModel.for_axis("pan", ["quantization", "offset"], {"offset.torque": 0.01})
    short = fit_model(
        closed_loop_log(true, duration_s=15.0, seed=2, disturbance_nm=0.002), _start(("offset",))
    )
    long = fit_model(
        closed_loop_log(true, duration_s=45.0, seed=2, disturbance_nm=0.002), _start(("offset",))
    )
    for name in ("inertia.J", "coulomb.torque", "offset.torque"):
        assert abs(long.params[name] - true.params[name]) < 4.0 * long.stderr[name], name
        assert long.stderr[name] < short.stderr[name], name


def test_gain_is_fixed_unless_asked_and_then_inertia_is_held() -> None:
    true = AxisModel.for_axis("pan", ["quantization"])
    meas = closed_loop_log(true, duration_s=15.0, seed=4)
    wrong_k = AxisModel.for_axis("pan", gain_nm_per_v=0.8 * true.gain_nm_per_v)
    fixed = fit_model(meas, wrong_k)
    assert fixed.model.gain_nm_per_v == 0.8 * true.gain_nm_per_v
    # Only torque/K is identifiable: with K fitted and J held at the truth, K comes back.
    with_gain = fit_model(meas, wrong_k.with_params({"inertia.J": true.params["inertia.J"]}), fit_gain=True)
    assert "inertia.J" not in with_gain.free
    assert with_gain.model.gain_nm_per_v == pytest.approx(true.gain_nm_per_v, rel=0.05)


def test_fit_reports_progress_and_can_be_cancelled() -> None:
    meas = closed_loop_log(AxisModel.for_axis("pan", ["quantization"]), duration_s=10.0, seed=1)
    seen: list[float] = []
    fit_model(meas, _start(()), progress=seen.append)
    assert seen and all(0.0 <= f <= 1.0 for f in seen)
    with pytest.raises(JobCancelled):
        fit_model(meas, _start(()), cancel=lambda: True)


def test_unknown_free_parameter_is_a_config_error() -> None:
    meas = closed_loop_log(AxisModel.for_axis("pan"), duration_s=5.0, seed=1)
    with pytest.raises(ConfigError, match="gravity.torque"):
        fit_model(meas, AxisModel.for_axis("pan"), free=["gravity.torque"])


def test_inverse_dynamics_method_agrees_with_k_step_on_clean_data() -> None:
    true = AxisModel.for_axis("pan", ["quantization", "offset"], {"offset.torque": -0.008})
    meas = closed_loop_log(true, duration_s=20.0, seed=8)
    idm = fit_model(meas, _start(("offset",)), method="inverse_dynamics")
    assert idm.n_evaluations == 0
    for name in ("inertia.J", "coulomb.torque", "offset.torque"):
        _assert_close(name, idm.params[name], true.params[name])
    assert np.isfinite(idm.inverse_dynamics_error_percent)


def test_inseparable_parameters_are_flagged_not_hidden() -> None:
    """Offset plus direction-dependent Coulomb: three levels for two directions of motion."""
    true = AxisModel.for_axis("pan", ["quantization", "offset"], {"offset.torque": 0.01})
    meas = closed_loop_log(true, duration_s=15.0, seed=3)
    clean = fit_model(meas, AxisModel.for_axis("pan", ["offset"]))
    assert clean.warnings == ()
    both = fit_model(meas, AxisModel.for_axis("pan", ["offset", "coulomb_asymmetry"]))
    # Three levels (Fc+, Fc−, offset) for two directions: any two of them trade off.
    trio = {"offset.torque", "coulomb_asymmetry.negative", "coulomb.torque"}
    pairs = {frozenset(p[:2]) for p in both.correlated}
    assert any(pair <= trio for pair in pairs), pairs
    assert any("cannot tell them apart" in w for w in both.warnings)


def test_a_fixed_asymmetry_is_kept_while_the_rest_is_refitted() -> None:
    """Regression: rebuilding models through AxisModel.with_params reset the negative-direction
    Coulomb torque to the positive one, so a fixed asymmetry was silently lost."""
    true = AxisModel.for_axis(
        "pan", ["quantization", "coulomb_asymmetry"], {"coulomb_asymmetry.negative": 0.075}
    )
    meas = closed_loop_log(true, duration_s=15.0, seed=12)
    start = AxisModel.for_axis("pan", ["coulomb_asymmetry"], {"coulomb_asymmetry.negative": 0.075})
    res = fit_model(meas, start, free=["inertia.J", "viscous.b", "coulomb.torque"])
    assert res.params["coulomb_asymmetry.negative"] == 0.075
    _assert_close("coulomb.torque", res.params["coulomb.torque"], 0.052)
