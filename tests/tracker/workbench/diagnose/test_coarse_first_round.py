"""A first round judges a torque effect beyond what a coarse encoder leaves (issue 9, session 13).

On a coarse encoder α, differentiated twice from the counts, carries noise of the size of its
signal, and the torque regression's inertia shrinks under it (errors in variables): its residual
holds the sensor's torque and the inertial torque the shrunken column no longer carries, neither
a function of θ or of the direction of motion. A torque effect's share is judged beyond that
floor, weighted with the inertia the k-step simulation judges by
(:func:`tracker.workbench.diagnose.sensor_floor.sensor_torque_sse`). The case is from truthgen
seed 9191's held-out half (spent, dev data since session 12).
"""

from __future__ import annotations

from functools import cache

import tests.truthgen.matrix as matrix
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.diagnose import Diagnosis, diagnose
from tracker.workbench.diagnose.screening import Structure, TorqueDesign
from tracker.workbench.diagnose.sensor_floor import sensor_torque_sse
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.idim import prepare_signals

TRACED_SEED = 9191
CASE = "coulomb_asymmetry-007"


@cache
def _case() -> tuple[dict[str, object], Measurement, AxisModel]:
    with matrix.seeded(TRACED_SEED):
        log, truth = matrix.generate_case(CASE)
    meas = Measurement(log.t, log.u, log.theta, CASE)
    model = AxisModel.for_axis(str(truth["axis"]), gain_nm_per_v=float(truth["gain_nm_per_v"]))  # type: ignore[arg-type]
    return truth, meas, model


@cache
def _diagnosis() -> Diagnosis:
    _, meas, model = _case()
    return diagnose(meas, model)


def test_the_floor_counts_the_inertial_torque_a_shrunken_inertia_leaves() -> None:
    """500 counts per revolution at 250 Hz: the regression's inertia is a seventh of the truth's.
    At its own inertia the encoder's torque is 11 % of the residual; with the inertia the
    simulation judges by (here the truth's), most of it, and never more than all."""
    truth, meas, _ = _case()
    params = truth["params"]
    assert isinstance(params, dict)
    sig = prepare_signals(meas)
    reg = TorqueDesign(sig, float(truth["gain_nm_per_v"]), 0.15).fit(  # type: ignore[arg-type]
        Structure.of(_case()[2])
    )
    j_reg = float(dict(zip(reg.names, reg.coef, strict=True))["Jm"])
    j_true = float(params["inertia.J"])
    assert j_reg < 0.3 * j_true, (j_reg, j_true)
    plain = sensor_torque_sse(sig, reg)
    weighted = sensor_torque_sse(sig, reg, j_true)
    assert plain < 0.2 * reg.sse_cv, (plain, reg.sse_cv)
    assert 0.5 * reg.sse_cv < weighted < reg.sse_cv, (weighted, reg.sse_cv)
    # An inertia no larger than the regression's changes nothing.
    assert sensor_torque_sse(sig, reg, 0.5 * j_reg) == plain


def test_a_large_coulomb_asymmetry_on_a_coarse_encoder_is_the_verdict() -> None:
    """Regression: an open-loop chirp, Coulomb 57 mN·m one way and 84 the other (47 %). It
    explained 4 % of the held-out residual torque against the 8 % bar and cut the k-step error
    by 4 % (t = 4.2): "significant but small", no verdict. Beyond the encoder's floor it explains
    18 %, and is named (a bias torque stands for it)."""
    truth, _, _ = _case()
    assert truth["hidden"] == ["coulomb_asymmetry"] and truth["encoder_counts_per_rev"] == 500
    d = _diagnosis()
    assert d.verdict in ("coulomb_asymmetry", "offset"), [
        (c.effect, c.significant, c.finding, round(c.screen_gain, 3)) for c in d.candidates
    ]
