"""A pair of hidden effects diagnosed in two rounds, as a user and ``bench/blind_matrix.py`` do it.

Diagnose; ``fit --effects <verdict>``; diagnose that fitted model. Cases come from the independent
truth generator (tests/truthgen), at its default seed or at one named.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import tests.truthgen.matrix as matrix
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.diagnose import Diagnosis, diagnose
from tracker.workbench.fit.fit import fit_model
from tracker.workbench.measurements.data import Measurement


@cache
def two_rounds(case_id: str, seed: int | None = None) -> tuple[dict[str, Any], Diagnosis, Diagnosis | None]:
    """The case's truth, the first diagnosis and the diagnosis of the model fitted with its verdict."""
    if seed is None:
        log, truth = matrix.generate_case(case_id)
    else:
        with matrix.seeded(seed):
            log, truth = matrix.generate_case(case_id)
    meas = Measurement(log.t, log.u, log.theta, str(truth["id"]))
    axis, gain = str(truth["axis"]), float(truth["gain_nm_per_v"])
    first = diagnose(meas, AxisModel.for_axis(axis, gain_nm_per_v=gain))  # type: ignore[arg-type]
    if first.verdict is None:
        return truth, first, None
    model = AxisModel.for_axis(axis, (first.verdict,), gain_nm_per_v=gain)  # type: ignore[arg-type]
    return truth, first, diagnose(meas, fit_model(meas, model).model)


@cache
def second_round(case_id: str, first_verdict: str, seed: int) -> tuple[dict[str, Any], Diagnosis]:
    """The truth and the second round's diagnosis after fitting ``first_verdict`` (the first
    round's verdict on this log, as a scorer's run recorded it; not rerun)."""
    with matrix.seeded(seed):
        log, truth = matrix.generate_case(case_id)
    meas = Measurement(log.t, log.u, log.theta, str(truth["id"]))
    axis, gain = str(truth["axis"]), float(truth["gain_nm_per_v"])
    model = AxisModel.for_axis(axis, (first_verdict,), gain_nm_per_v=gain)  # type: ignore[arg-type]
    return truth, diagnose(meas, fit_model(meas, model).model)
