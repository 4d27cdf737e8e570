"""A delay must beat the rigid body with its own inertia back where the axis slides
(sliding.lags_while_sliding).

Ground truth: the independent generator's seed 7 clean-029 (tilt, 500 Hz, open-loop voltage
ramps, a 1000-count encoder on the load, tanh friction, no delay, no latency): the torque
regression put the inertia at 1/60 of the truth (slow ramps barely accelerate the axis), and a
52 ms delay stood in for the axis' own lag J/b (55 ms) — "input–residual alignment best with the
command delayed 25.8 samples; explains 68 % of the held-out residual". With the inertia, viscous
and Coulomb friction refitted on the sliding windows with and without it, the delay gains 3 %
there. An open-loop log with a true drive delay is still named, within a millisecond.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.diagnose import diagnose
from tracker.workbench.measurements.data import read_log


@pytest.mark.slow
def test_outside_generator_ramps_on_a_coarse_load_encoder_get_no_delay(tmp_path: Path) -> None:
    outside = pytest.importorskip("bench.outside_gen.generate")
    from bench.outside_gen.loop import write_csv

    sc, run = outside.build_once("clean-029", 700029, None)
    truth = outside.truth_of(sc, run)
    assert truth["conditions"]["encoder"]["counts_per_rev"] == 1000  # the log of the report
    path = tmp_path / "clean.csv"
    write_csv(str(path), run)
    model = AxisModel.for_axis(str(truth["axis"]), gain_nm_per_v=float(truth["gain_nm_per_v"]))
    d = diagnose(read_log(path), model)
    assert d.verdict != "delay"
    assert not d.candidate("delay").significant

    # The same scenario with a true delay fits the inertia's lag, not the delay (the generator's
    # 6-sample delay read 58 ms, on main too): not a control. An open-loop log with a true one
    # is: seed 7 delay-003 (voltage steps, 200 Hz, 4096 counts on the load, 17.0 ms).
    sc_d, run_d = outside.build_once("delay-003", 706003, "delay")
    truth_d = outside.truth_of(sc_d, run_d)
    path_d = tmp_path / "delayed.csv"
    write_csv(str(path_d), run_d)
    model_d = AxisModel.for_axis(str(truth_d["axis"]), gain_nm_per_v=float(truth_d["gain_nm_per_v"]))
    d_d = diagnose(read_log(path_d), model_d)
    assert d_d.verdict == "delay"
    assert abs(d_d.candidate("delay").params["delay.seconds"] - sc_d.delay_s) < 1e-3
