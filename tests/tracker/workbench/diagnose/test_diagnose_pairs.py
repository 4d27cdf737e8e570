"""Two hidden effects: diagnose, add the verdict (refitted), diagnose again — both found, error falling."""

from __future__ import annotations

import pytest

from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.diagnose import diagnose

from ..hidden_cases import hidden_case

PAIRS = [("gravity", "delay"), ("offset", "ripple"), ("saturation", "stiction")]


@pytest.mark.parametrize("pair", PAIRS, ids=lambda p: "+".join(p))
def test_both_effects_of_a_pair_are_found_one_after_the_other(pair: tuple[str, str]) -> None:
    true, meas = hidden_case(pair, 211 + PAIRS.index(pair))
    model = AxisModel.for_axis("pan")
    found: list[str] = []
    fits: list[float] = []
    estimates: dict[str, float] = {}
    for _ in range(2):
        d = diagnose(meas, model)
        fits.append(d.fit_percent)
        assert d.verdict is not None, (
            f"after {found}: no verdict; {[(c.effect, c.significant) for c in d.candidates]}"
        )
        assert d.verdict in pair and d.verdict not in found
        found.append(d.verdict)
        cand = d.candidate(d.verdict)
        estimates.update(cand.params)
        # Add it: the candidate's model is the current one plus the effect, refitted (by
        # simulation for stiction, delay, saturation, compliance; by the torque regression else).
        assert cand.model is not None and cand.model.has(d.verdict)
        model = cand.model
    final = diagnose(meas, model)
    fits.append(final.fit_percent)
    assert set(found) == set(pair)
    assert final.verdict is None
    assert fits[0] < fits[1] < fits[2] or fits[2] - fits[0] > 0.1, f"fit % did not fall: {fits}"
    for name in true.params:
        if name.split(".")[0] in pair and not name.endswith((".phase", ".velocity")):
            assert estimates[name] == pytest.approx(true.params[name], rel=0.1), name
