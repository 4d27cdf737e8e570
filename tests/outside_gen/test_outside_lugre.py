"""LuGre friction on the outside generator's logs: richer than the model, no missing effect.

Two logs of the outside generator (seed 7, traced) whose friction is a LuGre bristle model with
pre-sliding, regenerated here and diagnosed through the engine's API, judged against their truth:

- a clean closed-loop step log on a 1000-count encoder: few moving samples determine the
  Coulomb torque of sliding poorly (0.012 ± 0.005 N·m, truly 0.024), and the break-away of its
  creeping starts measured over that estimate once read as static friction (+0.012 ± 0.002 N·m,
  "103 % above Coulomb"). The excess is a difference of two estimates: its uncertainty is both
  of theirs, and the log then names nothing;
- an open-loop multisine log with a real static friction and the same LuGre law still names it;
- a clean 2 kHz sines log whose stiff axis rings on the bristles at rest and after reversals
  (their resonance about 260 Hz) once named a belt of 172 Hz: a belt acts sliding or not, the
  bristles only there, so the "belt" that predicts nothing in steady sliding is not named;
- a LuGre log with a real belt (15.5 Hz) still names it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.outside_gen.regenerate import diagnosed


def _diagnosed(tmp_path: Path, name: str, seed: int, effect: str | None) -> tuple[dict[str, object], object]:
    truth, d = diagnosed(tmp_path, name, seed, effect)
    assert truth["conditions"]["friction_law"] == "lugre"  # type: ignore[index]
    return truth, d


@pytest.mark.slow
def test_a_clean_lugre_step_log_names_no_static_friction(tmp_path: Path) -> None:
    truth, d = _diagnosed(tmp_path, "clean-027", 700027, None)
    assert truth["effect"] is None
    assert d.verdict is None  # type: ignore[attr-defined]
    stiction = d.candidate("stiction")  # type: ignore[attr-defined]
    assert not stiction.significant
    assert "static friction, whatever the short prediction shows" not in stiction.evidence


@pytest.mark.slow
def test_a_lugre_log_with_static_friction_still_names_it(tmp_path: Path) -> None:
    truth, d = _diagnosed(tmp_path, "stiction-001", 704001, "stiction")
    assert truth["effect"] == "stiction"
    assert d.verdict == "stiction"  # type: ignore[attr-defined]
    fs = float(truth["hidden_params"]["stiction.static_torque"])  # type: ignore[index]
    fitted = float(d.candidate("stiction").params["stiction.static_torque"])  # type: ignore[attr-defined]
    assert np.isfinite(fitted) and 0.5 * fs < fitted < 2.0 * fs


@pytest.mark.slow
def test_a_clean_lugre_log_ringing_on_its_bristles_names_no_belt(tmp_path: Path) -> None:
    truth, d = _diagnosed(tmp_path, "clean-036", 300036, None)
    assert truth["effect"] is None and truth["conditions"]["transmission"] == "rigid"  # type: ignore[index]
    assert not d.candidate("compliance").significant  # type: ignore[attr-defined]
    assert d.verdict is None  # type: ignore[attr-defined]


@pytest.mark.slow
def test_a_lugre_log_with_a_belt_still_names_it(tmp_path: Path) -> None:
    truth, d = _diagnosed(tmp_path, "compliance-001", 110001, "compliance")
    assert truth["effect"] == "compliance"
    assert d.verdict == "compliance"  # type: ignore[attr-defined]
    f_true = float(truth["hidden_params"]["compliance.frequency"])  # type: ignore[index]
    f_fit = float(d.candidate("compliance").params["compliance.frequency"])  # type: ignore[attr-defined]
    # (its frequency is fitted 44 % high today, as belts of this generator often are: only the
    # naming is this test's concern)
    assert 0.5 * f_true < f_fit < 2.0 * f_true
