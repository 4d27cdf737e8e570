"""Start lags from rest (tracker.workbench.diagnose.startlags): a constant lag (a delay) against a
break-away level (stiction), on logs of the independent truth generator.

Open-loop voltage steps past Coulomb: with a drive delay every start comes the same time late
whatever the step's size; without one the first count comes within the time the model needs to
cover a count. In closed loop (a PID loop with a delay) the command keeps rising through the
delay, so the torque seen at every start is above Coulomb as if static friction held it: only
the timing tells them apart.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from tests.tracker.workbench.diagnose.step_logs import COULOMB_NM, RATE_HZ, regression_base, step_log
from tests.truthgen import matrix
from tests.truthgen.presets import GAIN_NM_PER_V
from tracker.plant.model import AxisModel
from tracker.workbench.diagnose.diagnose import diagnose
from tracker.workbench.diagnose.judgement import with_values
from tracker.workbench.diagnose.startlags import MIN_STARTS, StartLags, analyse_start_lags
from tracker.workbench.measurements.data import Measurement

DELAY_S = 0.012


def _steps(rng: np.random.Generator, n: int) -> np.ndarray:
    """Steps of 1.5-5 × Coulomb, 0.25 s on then 0.25 s at 0 V, alternating in sign."""
    u = np.zeros(n)
    i, hold, sign = int(0.25 * RATE_HZ), int(0.25 * RATE_HZ), 1.0
    while i + 2 * hold < n:
        u[i : i + hold] = sign * COULOMB_NM * rng.uniform(1.5, 5.0) / GAIN_NM_PER_V
        i += 2 * hold
        sign = -sign
    return u


@cache
def _log(delay: bool, seed: int = 11) -> Measurement:
    rng = np.random.default_rng(seed)
    u = _steps(rng, int(20 * RATE_HZ))
    hidden = {"delay.seconds": DELAY_S} if delay else {}
    return step_log(rng, u, hidden, 1.0e-3, f"steps-{'delay' if delay else 'clean'}")


def _lags(meas: Measurement) -> StartLags | None:
    sig, _, model, sliding_coulomb_nm = regression_base(meas)
    return analyse_start_lags(sig, model, sliding_coulomb_nm)


def test_a_delay_makes_every_start_late_by_the_same_time() -> None:
    lags = _lags(_log(True))
    assert lags is not None and lags.count >= MIN_STARTS
    assert lags.favours_delay() and not lags.favours_level()
    # The constant lag is the drive's delay plus the one-sample latency, within a few samples.
    assert abs(lags.delay_s - (DELAY_S + 1.0 / RATE_HZ)) < 4.0 / RATE_HZ


def test_the_clean_twin_starts_within_a_count_s_travel() -> None:
    lags = _lags(_log(False))
    assert lags is not None and lags.count >= MIN_STARTS
    assert not lags.favours_delay() and not lags.favours_level()
    # What lag there is, is the one-sample latency and where in the period the count changed.
    assert lags.delay_s < 3.0 / RATE_HZ


@cache
def _pid_delay_log() -> tuple[Measurement, dict[str, object]]:
    """The independent generator's case delay-001 of seed 6006 (development split): a PID loop
    at 2 kHz, a 500-count encoder, a drive delay of 11.2 ms."""
    with matrix.seeded(6006):
        log, truth = matrix.generate_case("delay-001")
    return Measurement(log.t, log.u, log.theta, "6006-delay-001"), truth


def test_closed_loop_delay_is_named_delay_not_stiction() -> None:
    """Regression: main named stiction (the start torques sat ~11 mN·m above the sliding
    Coulomb, as if held; the delay's grid sat on the user's inertia, failed a half and was never
    refitted by simulation)."""
    meas, truth = _pid_delay_log()
    assert truth["hidden"] == ["delay"]
    model = AxisModel.for_axis(str(truth["axis"]), gain_nm_per_v=float(truth["gain_nm_per_v"]))  # type: ignore[arg-type]
    d = diagnose(meas, model)
    assert d.verdict == "delay"
    assert "constant lag" in d.candidate("delay").evidence
    # Refitted by simulation the delay predicts better than the stiction the start torques
    # suggested (which may stay significant, second).
    assert d.candidate("delay").kstep_gain > d.candidate("stiction").kstep_gain


def test_with_the_delay_in_the_model_no_lag_is_left() -> None:
    """The second round: the model has the delay, so the starts come on time again."""
    sig, _, model, sliding_coulomb_nm = regression_base(_log(True))
    delayed = with_values(model, {"delay.seconds": DELAY_S + 1.0 / RATE_HZ}, add="delay")
    lags = analyse_start_lags(sig, delayed, sliding_coulomb_nm)
    assert lags is not None
    assert not lags.favours_delay()
    assert lags.delay_s < 3.0 / RATE_HZ


def test_a_level_within_the_stribeck_dip_of_coulomb_is_no_break_away() -> None:
    """A level 14 % above the sliding Coulomb is that Coulomb misestimated, however well it
    fits (an independent clean PID log's starts did); 80 % above is static friction."""
    fc = 0.05
    strong = {"count": 30, "delay_s": 0.008, "coulomb_nm": fc, "chi2_none": 400.0, "chi2_delay": 300.0}
    assert not StartLags(**strong, level_nm=1.14 * fc, chi2_level=30.0, dt_s=1e-3).favours_level()
    assert StartLags(**strong, level_nm=1.8 * fc, chi2_level=30.0, dt_s=1e-3).favours_level()
    # ... and only when it beats a constant lag on the log's own scatter.
    assert not StartLags(**strong, level_nm=1.8 * fc, chi2_level=290.0, dt_s=1e-3).favours_level()
