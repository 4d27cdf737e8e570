"""Stiction's size gate (judgement.negligible) on what the starts from rest measure, when they
reject the break-away the simulation fitted.

The refit by simulation can trade the break-away against Coulomb friction (outside generator m1
stiction-001: refitted 33 % *below* its own Coulomb, while the start times measured the true
level, χ² 36 against 855 for none) or fit the Karnopp stick to something else (m2 clean-031: a
4 % Stribeck bump refitted 64 % above Coulomb, where the start times put the level at Coulomb).
"""

from __future__ import annotations

from functools import cache
from types import SimpleNamespace

import numpy as np

from tests.tracker.workbench.diagnose.step_logs import COULOMB_NM, RATE_HZ, regression_base, step_log
from tests.truthgen.presets import GAIN_NM_PER_V
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.judgement import negligible, with_values
from tracker.workbench.diagnose.startlags import StartLags, analyse_start_lags

STATIC_RATIO = 1.6  # true break-away over Coulomb


@cache
def _ramps() -> tuple[StartLags, AxisModel, float]:
    """12 s of open-loop voltage ramps to 2-3 × Coulomb and back to 0 V (creeping starts),
    alternating in sign, on an axis with static friction 1.6 × Coulomb."""
    rng = np.random.default_rng(5)
    u = np.zeros(int(12 * RATE_HZ))
    i, sign = 200, 1.0
    while i + 800 < u.size:
        top = COULOMB_NM * rng.uniform(2.0, 3.0) / GAIN_NM_PER_V
        u[i : i + 400] = sign * np.linspace(0.0, top, 400)
        i, sign = i + 800, -sign
    hidden = {"stiction.static_torque": STATIC_RATIO * COULOMB_NM, "stiction.velocity": 0.01}
    meas = step_log(rng, u, hidden, 0.5e-3, "ramps-stiction")
    sig, _, model, sliding_nm = regression_base(meas)
    lags = analyse_start_lags(sig, model, sliding_nm)
    assert lags is not None
    return lags, model, sliding_nm


def test_the_starts_measure_the_break_away_and_reject_a_traded_refit() -> None:
    lags, model, fc = _ramps()
    assert lags.favours_level()
    assert abs(lags.level_nm / (STATIC_RATIO * COULOMB_NM) - 1.0) < 0.1
    # A refit that put Coulomb 5 % high and the break-away 30 % under the sliding Coulomb.
    traded = with_values(
        model,
        {"coulomb.torque": 1.05 * fc, "stiction.static_torque": 0.7 * fc, "stiction.velocity": 1.0},
        add="stiction",
    )
    assert negligible("stiction", traded) is not None  # the fitted value alone: "a Stribeck dip"
    ctx: object = SimpleNamespace(breakaway=None, start_lags=lags)
    assert lags.rejects_level(0.7 * fc)
    assert negligible("stiction", traded, ctx) is None  # type: ignore[arg-type]
    # A refit near the measured level is not rejected, and judged as fitted.
    assert not lags.rejects_level(lags.level_nm)


def _lags(level_nm: float, chi2: tuple[float, ...]) -> StartLags:
    levels = tuple(1.0 + 0.1 * k for k in range(1, len(chi2) + 1))
    return StartLags(13, 0.0, level_nm, 1.0, 6.0, 6.0, min(chi2), 0.005, levels, chi2)


def test_a_refit_level_the_starts_reject_is_replaced_by_the_measured_one() -> None:
    # The starts put the level at Coulomb (χ² 6 there, as for none), a refit level 60 % above
    # it scores χ² 40: rejected, so the size judged is the measured one, none above Coulomb.
    lags = _lags(1.0, (6.0, 7.0, 9.0, 14.0, 20.0, 40.0, 60.0))
    assert lags.rejects_level(1.6) and not lags.rejects_level(1.2)
    model = with_values(
        AxisModel.for_axis("pan", gain_nm_per_v=GAIN_NM_PER_V),
        {"coulomb.torque": 1.0, "stiction.static_torque": 1.6, "stiction.velocity": 0.001},
        add="stiction",
    )
    ctx: object = SimpleNamespace(breakaway=None, start_lags=lags)
    assert negligible("stiction", model) is None
    assert negligible("stiction", model, ctx) is not None  # type: ignore[arg-type]
    # Starts a constant lag explains far better (a drive delay: outside gen2 m2 stiction-000 and
    # m3 delay-000) measure no level and reject no refit.
    lagged = StartLags(13, 0.02, 1.0, 1.0, 60.0, 6.0, 60.0, 0.005, lags.levels_nm[:3], (60.0, 70.0, 200.0))
    assert not lagged.rejects_level(1.2)
    # ... judged on the lag's own scatter (m2 stiction-000: χ² 8914 for a level, 4475 for a lag,
    # 25 starts: 24 scatters of the lag's, 12 of the level's).
    levels = tuple(0.0465 * (1.0 + 0.01 * k) for k in range(1, 101))
    chi2 = tuple(8914.0 + 200.0 * k for k in range(1, 101))
    lagged = StartLags(25, 0.0185, 0.0465, 0.0465, 8914.0, 4475.0, 8914.0, 0.0005, levels, chi2)
    assert not lagged.rejects_level(0.0847)
    # No levels tried (too few starts reached one): nothing to reject with.
    assert not StartLags(13, 0.0, 1.0, 1.0, 6.0, 6.0, 6.0, 0.005).rejects_level(1.6)
