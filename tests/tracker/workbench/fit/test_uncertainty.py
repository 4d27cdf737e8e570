"""Each fitted parameter's certainty: flagged when this run does not pin it, with the experiment."""

from __future__ import annotations

from tracker.plant.effects import CATALOGUE
from tracker.workbench.fit.uncertainty import parameter_certainty


def test_flags_a_large_relative_error_and_names_the_experiment() -> None:
    out = {
        c.name: c
        for c in parameter_certainty(
            {"viscous.b": 1e-3, "inertia.J": 2e-3}, {"viscous.b": 2.5e-4, "inertia.J": 1e-5}
        )
    }
    b, j = out["viscous.b"], out["inertia.J"]
    assert b.poorly_determined and "25 %" in b.reason
    assert b.experiment == CATALOGUE["viscous"].experiment and b.experiment
    assert not j.poorly_determined and abs(j.relative_stderr - 0.005) < 1e-12


def test_a_correlation_is_named_but_flags_only_the_parameter_it_leaves_loose() -> None:
    """Regression (issue 9, session 8): the fitter reports a pair correlated beyond 0.95 when it
    costs one of them precision, and both were flagged. The standard errors are the marginal
    ones of the full covariance, so the correlation is already in them: the sharp partner
    (gravity at ±1 %) is pinned by the log whatever its partner does, and flagging it took
    right values (and wrong ones) out of the "determined" count by a rule that is no measure
    of the log's information on them."""
    out = {
        c.name: c
        for c in parameter_certainty(
            {"gravity.torque": 0.1, "offset.torque": 0.01},
            {"gravity.torque": 1e-3, "offset.torque": 4e-3},
            (("gravity.torque", "offset.torque", -0.97),),
        )
    }
    g, o = out["gravity.torque"], out["offset.torque"]
    assert all("correlated with" in c.reason for c in out.values())
    assert o.poorly_determined and "40 %" in o.reason
    assert not g.poorly_determined


def test_every_catalogue_effect_with_fitted_parameters_says_how_to_pin_them() -> None:
    for name, effect in CATALOGUE.items():
        if any(p.fit for p in effect.params) and name != "quantization":
            assert effect.experiment, name


def test_a_value_on_a_catalogue_bound_is_flagged_whatever_its_standard_error() -> None:
    out = {
        c.name: c
        for c in parameter_certainty(
            {"compliance.frequency": 0.5, "compliance.damping": 0.1, "viscous.b": 0.0},
            {"compliance.frequency": 0.02, "compliance.damping": 0.001, "viscous.b": 1e-4},
        )
    }
    f = out["compliance.frequency"]
    assert f.poorly_determined and "lower bound 0.5 Hz" in f.reason
    assert not out["compliance.damping"].poorly_determined
    # zero is a physical value, not a range's end: b = 0 is judged by its (infinite) relative error
    assert "bound" not in out["viscous.b"].reason and out["viscous.b"].poorly_determined


def test_bounds_are_judged_on_their_own_scale_and_phases_have_none() -> None:
    """A Stribeck velocity of 0.03 rad/s is not "at" the bound 1e-5 of a range up to 100, and a
    phase of 3.14 is not at the end of a circle."""
    out = {
        c.name: c
        for c in parameter_certainty(
            {"stiction.velocity": 0.03, "ripple.phase": 3.1415, "saturation.limit": 10.0},
            {"stiction.velocity": 1e-4, "ripple.phase": 0.01, "saturation.limit": 0.01},
            upper_bounds={"saturation.limit": 10.0},  # the rail of a log within ±10 V
        )
    }
    assert not out["stiction.velocity"].poorly_determined
    assert not out["ripple.phase"].poorly_determined
    assert "upper bound 10 V" in out["saturation.limit"].reason
    # Without the log's rail the catalogue admits any drive's limit (up to 1e6 V).
    alone = parameter_certainty({"saturation.limit": 10.0}, {"saturation.limit": 0.01})
    assert not alone[0].poorly_determined
