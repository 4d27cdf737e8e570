"""Residual analysis: whiteness and input-independence bounds behave as the statistics say."""

import numpy as np
import pytest

from tracker.workbench.compare.residuals import analyse_residuals, autocorrelation

DT = 1e-3


def _ar1(rng: np.random.Generator, n: int, a: float) -> np.ndarray:
    x = np.zeros(n)
    e = rng.normal(size=n)
    for k in range(1, n):
        x[k] = a * x[k - 1] + e[k]
    return x


def test_white_residual_stays_inside_the_99_percent_bound() -> None:
    rng = np.random.default_rng(0)
    res = analyse_residuals(rng.normal(size=20000), rng.normal(size=20000), DT, max_lag_s=0.1)
    assert res.autocorr_bound == pytest.approx(2.5758 / np.sqrt(20000), rel=1e-3)
    assert res.autocorr_outside_fraction <= 0.03
    assert res.white
    assert res.xcorr_outside_fraction <= 0.03


def test_cross_correlation_bound_accounts_for_coloured_signals() -> None:
    """Independent but strongly coloured e and u: the naive 2.58/√N bound is crossed at many
    lags, Ljung's P-weighted bound only rarely."""
    outside = []
    for seed in range(5):
        rng = np.random.default_rng(seed)
        e, u = _ar1(rng, 8000, 0.97), _ar1(rng, 8000, 0.97)
        res = analyse_residuals(e, u, DT, max_lag_s=0.05)
        naive = np.mean(np.abs(res.xcorr) > 2.5758 / np.sqrt(8000))
        outside.append(res.xcorr_outside_fraction)
        assert res.xcorr_bound > 3 * 2.5758 / np.sqrt(8000)
        assert naive >= res.xcorr_outside_fraction
    assert np.mean(outside) < 0.1


def test_residual_that_follows_the_input_late_peaks_at_that_lag() -> None:
    rng = np.random.default_rng(1)
    u = rng.normal(size=10000)
    lag = 14
    e = np.zeros_like(u)
    e[lag:] = 0.5 * u[:-lag]
    e += 0.2 * rng.normal(size=u.size)
    res = analyse_residuals(e, u, DT, max_lag_s=0.05)
    assert res.xcorr_peak_lag_s == pytest.approx(0.014)
    assert not res.independent_of_input


def test_autocorrelation_of_ar1_decays_geometrically() -> None:
    rng = np.random.default_rng(2)
    r = autocorrelation(_ar1(rng, 50000, 0.8), 3)
    assert r[0] == 1.0
    assert r[1:] == pytest.approx([0.8, 0.64, 0.512], abs=0.03)
