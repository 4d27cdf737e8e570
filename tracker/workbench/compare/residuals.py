"""Residual analysis as in identification practice (Ljung's ``resid``): whiteness and independence.

Autocorrelation of the residual e over lags 0..M with the 99 % bound ±2.576/√N of a white
sequence, and the cross-correlation of the input u with e over lags −M..M. The cross-correlation
bound accounts for both signals being coloured (Ljung, System Identification, 2nd ed., eq. 16.64):
under independence √N·R̂_eu(τ) is normal with variance P = Σ_k R_e(k) R_u(k), so the normalised
bound is 2.576·√(Σ_k r_e(k) r_u(k) / N). A positive lag τ means the residual follows the input
τ seconds later (how a missing delay shows up).

The residual spectrum (Welch) says at which frequencies the model is wrong.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import welch

FloatArray = NDArray[np.float64]

Z_99 = 2.5758293035489


@dataclass(frozen=True, slots=True)
class ResidualAnalysis:
    """Correlation analysis of a residual. Arrays are for plots; the rest are summary numbers.

    ``autocorr`` has shape (M+1,) at ``autocorr_lags_s``; ``xcorr`` shape (2M+1,) at
    ``xcorr_lags_s`` (negative lags: residual leads the input). Bounds are 99 % (one-sided
    magnitude). ``spectrum_psd`` is the residual's power spectral density at ``spectrum_freq_hz``.
    """

    autocorr_lags_s: FloatArray
    autocorr: FloatArray
    autocorr_bound: float
    autocorr_outside_fraction: float
    xcorr_lags_s: FloatArray
    xcorr: FloatArray
    xcorr_bound: float
    xcorr_outside_fraction: float
    xcorr_peak_lag_s: float
    xcorr_peak: float
    spectrum_freq_hz: FloatArray
    spectrum_psd: FloatArray
    spectrum_peak_hz: float

    @property
    def white(self) -> bool:
        """Residual looks white: at most 1 % of lags ≥ 1 outside the bound."""
        return self.autocorr_outside_fraction <= 0.01

    @property
    def independent_of_input(self) -> bool:
        """No lag of the input–residual cross-correlation outside its bound."""
        return self.xcorr_outside_fraction == 0.0

    def to_dict(self, arrays: bool = False) -> dict[str, object]:
        """JSON-ready summary (and the arrays for plots when ``arrays``)."""
        out: dict[str, object] = {
            "autocorr_bound": self.autocorr_bound,
            "autocorr_outside_fraction": self.autocorr_outside_fraction,
            "white": self.white,
            "xcorr_bound": self.xcorr_bound,
            "xcorr_outside_fraction": self.xcorr_outside_fraction,
            "xcorr_peak_lag_s": self.xcorr_peak_lag_s,
            "xcorr_peak": self.xcorr_peak,
            "independent_of_input": self.independent_of_input,
            "spectrum_peak_hz": self.spectrum_peak_hz,
        }
        if arrays:
            out.update(
                autocorr_lags_s=self.autocorr_lags_s.tolist(),
                autocorr=self.autocorr.tolist(),
                xcorr_lags_s=self.xcorr_lags_s.tolist(),
                xcorr=self.xcorr.tolist(),
                spectrum_freq_hz=self.spectrum_freq_hz.tolist(),
                spectrum_psd=self.spectrum_psd.tolist(),
            )
        return out


def _raw_xcorr(a: FloatArray, b: FloatArray, max_lag: int) -> FloatArray:
    """c[τ] = (1/N) Σ_t a(t) b(t−τ) for τ = −max_lag..max_lag (zero-mean inputs). Shape (2M+1,)."""
    n = a.size
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    fa = np.fft.rfft(a, nfft)
    fb = np.fft.rfft(b, nfft)
    full = np.fft.irfft(fa * np.conj(fb), nfft) / n
    return np.concatenate([full[nfft - max_lag :], full[: max_lag + 1]])


def autocorrelation(x: FloatArray, max_lag: int) -> FloatArray:
    """Normalised autocorrelation r(0..max_lag) of ``x`` (r(0) = 1). Shape (max_lag+1,)."""
    z = np.asarray(x, dtype=float) - float(np.mean(x))
    c = _raw_xcorr(z, z, max_lag)[max_lag:]
    return c / c[0] if c[0] > 0 else np.zeros_like(c)


def analyse_residuals(
    residual: FloatArray, u_v: FloatArray, dt_s: float, max_lag_s: float = 0.1
) -> ResidualAnalysis:
    """Whiteness, input independence and spectrum of ``residual`` (shape (n,)) against ``u_v``.

    ``max_lag_s`` sets M = max_lag_s/dt_s lags (at least 5, at most n/4).
    """
    e = np.asarray(residual, dtype=float)
    u = np.asarray(u_v, dtype=float)
    n = e.size
    m = int(min(max(5, round(max_lag_s / dt_s)), max(5, n // 4)))
    e0 = e - e.mean()
    u0 = u - u.mean()
    se, su = float(np.std(e0)), float(np.std(u0))
    # One FFT per signal; auto- and cross-correlations from the products.
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    fe = np.fft.rfft(e0, nfft)
    fu = np.fft.rfft(u0, nfft)
    # Ljung's P sums over all lags where both autocorrelations matter (|k| ≤ n/4).
    kmax = max(m, min(n // 4, 20 * m))
    ce = np.fft.irfft(fe * np.conj(fe), nfft)[: kmax + 1] / n
    cu = np.fft.irfft(fu * np.conj(fu), nfft)[: kmax + 1] / n
    re_all = ce / ce[0] if ce[0] > 0 else np.zeros_like(ce)
    ru_all = cu / cu[0] if cu[0] > 0 else np.zeros_like(cu)
    lags = np.arange(m + 1, dtype=np.float64) * dt_s
    re = re_all[: m + 1]
    a_bound = Z_99 / math.sqrt(n)
    a_out = float(np.mean(np.abs(re[1:]) > a_bound)) if m > 0 else 0.0
    if se > 0 and su > 0:
        full = np.fft.irfft(fe * np.conj(fu), nfft) / n
        xc = np.concatenate([full[nfft - m :], full[: m + 1]]) / (se * su)
        p = float(re_all[0] * ru_all[0] + 2.0 * np.sum(re_all[1:] * ru_all[1:]))
        x_bound = Z_99 * math.sqrt(max(p, 1.0 / n) / n)
    else:
        xc = np.zeros(2 * m + 1)
        x_bound = Z_99 / math.sqrt(n)
    x_lags = np.arange(-m, m + 1, dtype=np.float64) * dt_s
    k_peak = int(np.argmax(np.abs(xc)))
    x_out = float(np.mean(np.abs(xc) > x_bound))
    nper = int(min(n, max(64, 2 ** int(math.log2(max(n // 8, 64))))))
    f, psd = welch(e0, fs=1.0 / dt_s, nperseg=nper)
    peak_hz = float(f[1 + int(np.argmax(psd[1:]))]) if f.size > 1 else 0.0
    return ResidualAnalysis(
        lags,
        re,
        a_bound,
        a_out,
        x_lags,
        xc,
        x_bound,
        x_out,
        float(x_lags[k_peak]),
        float(xc[k_peak]),
        f,
        psd,
        peak_hz,
    )


__all__ = ["ResidualAnalysis", "analyse_residuals", "autocorrelation"]
