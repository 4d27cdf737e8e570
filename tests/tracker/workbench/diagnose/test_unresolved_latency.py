"""A verdict found only once an unresolved computational latency is in the model is not named.

A latency of about one sample is adopted before the other candidates are judged (the command logged
at row i acting from row i + 1 is part of the loop, not a missing effect). When the encoder's counts
come further apart than that latency while moving, the log cannot say whether it is there; a
verdict must then hold with and without it. Regression on a clean log of the independent truth
generator (seed 6006, its development half; the held-out half is never run here).
"""

from __future__ import annotations

import tests.truthgen.matrix as matrix
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.diagnose import diagnose
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.idim import encoder_timing_s

SEED = 6006


def test_a_dead_band_seen_only_with_an_unresolved_latency_is_not_named() -> None:
    """Regression (seed 6006, clean-048): a 250 Hz lead-lag log on tilt, Karnopp friction, a
    1000-count encoder, no latency. The diagnosis adopted a 1.5-sample "computational latency"
    (6 ms) that the encoder cannot resolve (its counts come 12 ms apart while moving); with it in
    the model a dead band of 4 counts passed its bar (18 % of the residual torque beyond a count's
    flicker, against 15 %) and became the verdict. Without the latency it is not significant."""
    with matrix.seeded(SEED):
        log, truth = matrix.generate_case("clean-048")
    assert truth["hidden"] == [] and truth["latency_samples"] == 0
    meas = Measurement(log.t, log.u, log.theta, str(truth["id"]))
    model = AxisModel.for_axis(str(truth["axis"]), gain_nm_per_v=float(truth["gain_nm_per_v"]))  # type: ignore[arg-type]
    d = diagnose(meas, model)
    latency = d.candidate("delay")
    assert latency.finding == "computational latency"
    assert latency.params["delay.seconds"] < encoder_timing_s(meas.theta_rad, meas.dt_s)
    assert d.verdict is None
    backlash = d.candidate("backlash")
    assert not backlash.significant
    assert backlash.finding == "only with an unresolved latency"
    assert any(n.startswith("backlash is significant only with the computational latency") for n in d.notes)
