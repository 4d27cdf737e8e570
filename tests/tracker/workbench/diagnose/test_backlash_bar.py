"""The backlash verdict's bar on the k-step simulation: it may make the 30 ms prediction worse
(where the load sits in the gap is not observable over such a window) but not significantly."""

from __future__ import annotations

from typing import Any

from tracker.workbench.diagnose.judgement import (
    MAX_BACKLASH_KSTEP_RATIO,
    MAX_BACKLASH_KSTEP_WORSE_T,
    _backlash_significant,
)
from tracker.workbench.diagnose.kstep import Comparison
from tracker.workbench.diagnose.screening import Screen


def _screen(gain_cv: float = 0.4, beyond_flicker: float = 0.3) -> Screen:
    none: Any = None
    return Screen(
        "backlash",
        none,
        none,
        {"backlash.width": 0.01},
        {},
        gain_cv,
        1e-8,
        True,
        {"beyond_flicker": beyond_flicker},
    )


def test_a_gap_that_worsens_the_prediction_within_its_scatter_stands() -> None:
    # True gaps on two independent development sets: k-step error up to +29 % at t = -2.9.
    assert _backlash_significant(_screen(), {}, Comparison(-0.29, -2.9))
    # A large but scattered change (a short log's few windows) is not evidence against it.
    assert _backlash_significant(_screen(), {}, Comparison(-1.5, -1.2))


def test_a_gap_that_makes_the_prediction_significantly_worse_is_refused() -> None:
    # A clean log's false gap: k-step error +127 % at t = -8 (the old bar, +200 %, let it through).
    assert not _backlash_significant(_screen(), {}, Comparison(-1.27, -8.0))
    assert not _backlash_significant(_screen(), {}, Comparison(-0.2, -MAX_BACKLASH_KSTEP_WORSE_T - 0.1))


def test_the_screen_must_still_explain_the_torque_beyond_the_flicker() -> None:
    assert not _backlash_significant(_screen(beyond_flicker=0.05), {}, Comparison(0.3, 5.0))
    assert not _backlash_significant(_screen(gain_cv=0.05), {}, Comparison(0.3, 5.0))


def test_a_gap_whose_prediction_fails_outright_is_refused_however_it_scatters() -> None:
    # Outside generator, clean logs of raw steps through a cascade that hunts a count either way
    # at each hold (m1 clean-011, m2 clean-018/029, m3 clean-033): a "gap" of up to 1850 counts,
    # k-step error 11-57 times the error without, at t = -2.7 to -3.6 (a few windows fail
    # outright, so the scatter is as large as the mean).
    for improvement, t in ((-39.3, -2.97), (-56.5, -2.68), (-10.2, -3.28), (-13.4, -3.65)):
        assert not _backlash_significant(_screen(), {}, Comparison(improvement, t))
    # A true gap of the same generator: 4.7 times the error (m2 backlash-000) stands.
    assert _backlash_significant(_screen(), {}, Comparison(-3.72, -3.90))
    assert not _backlash_significant(_screen(), {}, Comparison(1.0 - MAX_BACKLASH_KSTEP_RATIO, -1.0))
