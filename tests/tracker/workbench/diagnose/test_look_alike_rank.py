"""Gravity against its constant look-alike (a bias torque) in the ranking: the held-out halves
decide, and the verdict must not contradict the CLI's own note about them."""

from __future__ import annotations

from typing import Any

import numpy as np

from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.judgement import Judged, look_alike_notes, rank
from tracker.workbench.diagnose.kstep import Comparison, KStepScore
from tracker.workbench.diagnose.screening import Screen
from tracker.workbench.measurements.idim import Regression


class _Judge:
    """What rank() asks of the k-step judge when both stories predict alike by simulation."""

    def compare(self, base: KStepScore, cand: KStepScore) -> Comparison:
        return Comparison(1.0 - cand.sse / base.sse, 0.5, 0.0)

    def half_gains(self, base: KStepScore, cand: KStepScore) -> tuple[float, float]:
        return (0.0, 0.0)


def _row(effect: str, sse_torque: float, sse_kstep: float, versus: tuple[float, float] | None) -> Judged:
    none: Any = None
    names = ("inertia.J", "viscous.b", "coulomb.torque", effect)
    reg = Regression(
        names, np.zeros(4), np.eye(4), sse_torque, sse_torque, np.zeros(2), np.zeros(1), 5000, 2000.0
    )
    scr = Screen(effect, none, reg, {}, {}, 0.85, 1e-12, True, {})
    model = AxisModel.create(0.1, {}, (effect,))
    score = KStepScore(np.array([sse_kstep]), np.zeros(1), 99.0)
    row = Judged(effect, scr, model, score, Comparison(1.0 - sse_kstep / 1.0, 5.0, 0.8), True, True)
    if versus is not None:
        row.versus["offset"] = versus
    return row


def _ranked(versus: tuple[float, float]) -> list[str]:
    # The torque regression: gravity explains more (F-test p far below 1e-3); the k-step error
    # with gravity a little lower, so gravity sorts first.
    rows = [_row("gravity", 0.90, 0.187, versus), _row("offset", 1.00, 0.188, None)]
    judge: Any = _Judge()
    rank(rows, judge)
    return [r.effect for r in rows]


def test_a_bias_torque_leads_when_a_held_out_half_says_gravity_predicts_no_better() -> None:
    # Outside generator m1 offset-001: gravity changed the bias torque's held-out k-step error by
    # +1 % and -2 %, and was named though the note said naming it needs -5 % on each half.
    assert _ranked((-0.01, 0.02))[0] == "offset"
    assert _ranked((0.03, -0.01))[0] == "offset"  # m1 coulomb_asymmetry-002: -3 % and +1 %


def test_gravity_leads_when_the_halves_agree_or_determine_it() -> None:
    assert _ranked((0.06, 0.08))[0] == "gravity"  # the log determines the slope
    # Both halves better, one under the bar (truthgen gravity+delay: -3 % and -8 %): the torque
    # regression's F-test names it, and the note says so.
    order = _ranked((0.03, 0.08))
    assert order[0] == "gravity"


def test_the_note_states_the_rule_the_verdict_follows() -> None:
    rows = [_row("gravity", 0.90, 0.187, (-0.01, 0.02)), _row("offset", 1.00, 0.188, None)]
    judge: Any = _Judge()
    rank(rows, judge)
    (note,) = look_alike_notes(rows)
    assert "(named: offset)" in note and "no half worse" in note
