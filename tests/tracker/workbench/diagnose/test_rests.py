"""Stiction on open-loop voltage steps: rests that held a torque beyond Coulomb
(tracker.workbench.diagnose.rests), on logs of the independent truth generator.

The axis is the truth generator's (its own integrator and Karnopp stick-slip), driven open loop
by voltage steps that hold the torque between the Coulomb and the break-away torque (the axis
never moves) or past the break-away (it starts at once), with a slow disturbance; its twin
without stiction (same steps, same disturbance) is the clean log. Breaks from rest after a
step say nothing about the break-away (the axis starts at once whatever it is), so the
break-away analysis finds no creeping start: the rests are the evidence.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from tests.tracker.workbench.diagnose.step_logs import (
    COULOMB_NM,
    RATE_HZ,
    base_model,
    regression_base,
    step_log,
)
from tests.truthgen.presets import GAIN_NM_PER_V
from tracker.workbench.diagnose.breakaway import analyse_breakaway
from tracker.workbench.diagnose.diagnose import Diagnosis, diagnose
from tracker.workbench.diagnose.rests import RestHolds, analyse_rests
from tracker.workbench.measurements.data import Measurement

STATIC_NM = 0.11  # break-away twice Coulomb


def _steps(rng: np.random.Generator, n: int) -> np.ndarray:
    """Alternating steps, each 0.25 s then 0.25 s at 0 V: every third past the break-away
    (1.3-2.2 × it), the others between Coulomb and break-away (1.35-1.8 × Coulomb)."""
    u = np.zeros(n)
    k, i, sign = 0, int(0.25 * RATE_HZ), 1.0
    hold = int(0.25 * RATE_HZ)
    while i + 2 * hold < n:
        torque = STATIC_NM * rng.uniform(1.3, 2.2) if k % 3 == 0 else COULOMB_NM * rng.uniform(1.35, 1.8)
        u[i : i + hold] = sign * torque / GAIN_NM_PER_V
        i += 2 * hold
        k += 1
        sign = -sign if k % 2 == 0 else sign
    return u


@cache
def _log(stiction: bool, seed: int = 7) -> Measurement:
    rng = np.random.default_rng(seed)
    u = _steps(rng, int(20 * RATE_HZ))
    hidden = {"stiction.static_torque": STATIC_NM, "stiction.velocity": 0.05} if stiction else {}
    return step_log(rng, u, hidden, 1.5e-3, f"steps-{'stiction' if stiction else 'clean'}")


def _rests(meas: Measurement) -> RestHolds | None:
    sig, reg, model, sliding_coulomb_nm = regression_base(meas)
    return analyse_rests(sig, reg, model, sliding_coulomb_nm)


@cache
def _diagnosis(stiction: bool) -> Diagnosis:
    return diagnose(_log(stiction), base_model())


def test_rests_that_held_between_coulomb_and_break_away_establish_stiction() -> None:
    rests = _rests(_log(True))
    assert rests is not None and rests.established() is not None
    assert rests.held >= 5
    # The held levels bound the break-away from below and stay under it.
    assert COULOMB_NM < rests.level_nm < STATIC_NM * 1.05


def test_the_clean_twin_holds_nothing() -> None:
    rests = _rests(_log(False))
    assert rests is not None and rests.rests >= 10
    assert rests.held == 0 and rests.established() is None


def test_steps_give_the_break_away_analysis_no_creeping_start() -> None:
    """Why the rests are needed: no start from rest creeps up to the break-away."""
    ba = analyse_breakaway(_log(True), base_model())
    assert ba is None or ba.count < 4


def test_diagnosis_names_stiction_on_steps_that_held() -> None:
    """Regression: main named nothing (the break-away analysis found no event)."""
    d = _diagnosis(True)
    assert d.verdict == "stiction"
    assert "rests held a torque beyond Coulomb" in d.candidate("stiction").evidence
    static = d.candidate("stiction").params["stiction.static_torque"]
    assert COULOMB_NM * 1.25 < static < STATIC_NM * 1.5


def test_diagnosis_of_the_clean_twin_names_nothing() -> None:
    d = _diagnosis(False)
    assert d.verdict is None
