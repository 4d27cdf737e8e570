"""An outside-generator log regenerated from its seed and diagnosed through the engine's API."""

from __future__ import annotations

from pathlib import Path

from bench.outside_gen.generate import generate
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.diagnose import Diagnosis, diagnose
from tracker.workbench.measurements.data import read_log


def diagnosed(
    tmp_path: Path, name: str, log_seed: int, effect: str | None
) -> tuple[dict[str, object], Diagnosis]:
    """The log's truth and the diagnosis of its CSV from the base model of its axis and gain."""
    truth = generate(tmp_path, name, log_seed, effect)
    meas = read_log(str(tmp_path / f"{name}.csv"))
    model = AxisModel.for_axis(str(truth["axis"]), (), {}, gain_nm_per_v=float(truth["gain_nm_per_v"]))  # type: ignore[arg-type]
    return truth, diagnose(meas, model)
