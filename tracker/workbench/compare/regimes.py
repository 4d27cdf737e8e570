"""Where the model is wrong: prediction error broken down by motion regime, position, time, frequency.

A k-step prediction ending at sample t covers the window [t−k, t]; it belongs to a regime by
what happened in that window (a reversal anywhere in it, a hold over all of it, ...), because
that is where its error was made. Regimes overlap (a reversal is also low speed), so the
shares do not add up to 100 %. The telling number is ``concentration`` = share of the squared
error ÷ share of the time: 1 means the error is spread evenly, 5 means the regime holds five
times its share of the error ("error concentrates at velocity reversals").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import maximum_filter1d, minimum_filter1d

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

REGIME_NAMES = ("reversal", "start", "hold", "low_speed", "high_speed", "high_accel", "moving")
# Thresholds as fractions of the run's 95th-percentile speed / acceleration.
HOLD_SPEED_FRACTION = 0.02
LOW_SPEED_FRACTION = 0.15
HIGH_SPEED_FRACTION = 0.5
HIGH_ACCEL_FRACTION = 0.5
# A reversal must be clear: moving above the hold speed on both sides within this time.
REVERSAL_SPAN_S = 0.1
POSITION_BINS = 8
TIME_SEGMENTS = 10
FREQUENCY_BANDS_HZ = ((0.0, 1.0), (1.0, 5.0), (5.0, 20.0), (20.0, 100.0), (100.0, math.inf))


@dataclass(frozen=True, slots=True)
class RegimeError:
    """Prediction error inside one regime (or bin): RMS, share of the total squared error."""

    rms_deg: float
    share_of_error_percent: float
    samples: int
    fraction_of_time: float

    @property
    def concentration(self) -> float:
        """Share of error ÷ share of time (1 = evenly spread; 0 when the regime is empty)."""
        return (
            self.share_of_error_percent / (100.0 * self.fraction_of_time)
            if self.fraction_of_time > 0
            else 0.0
        )

    def to_dict(self) -> dict[str, float | int]:
        """JSON-ready."""
        return {
            "rms_deg": self.rms_deg,
            "share_of_error_percent": self.share_of_error_percent,
            "samples": self.samples,
            "fraction_of_time": self.fraction_of_time,
            "concentration": self.concentration,
        }


@dataclass(frozen=True, slots=True)
class RegimeBreakdown:
    """Error by motion regime, position bin, time segment and frequency band.

    ``regimes`` maps names of :data:`REGIME_NAMES` to errors. ``position_bins`` and
    ``time_segments`` are ordered (label, error) pairs, labels like ``"-0.52..-0.39 rad"``;
    ``frequency_bands`` pairs a band label with the share of residual power in it.
    """

    regimes: Mapping[str, RegimeError]
    position_bins: tuple[tuple[str, RegimeError], ...]
    time_segments: tuple[tuple[str, RegimeError], ...]
    frequency_bands: tuple[tuple[str, float], ...]

    def to_dict(self) -> dict[str, object]:
        """JSON-ready."""
        return {
            "regimes": {k: v.to_dict() for k, v in self.regimes.items()},
            "position_bins": {k: v.to_dict() for k, v in self.position_bins},
            "time_segments": {k: v.to_dict() for k, v in self.time_segments},
            "frequency_bands_percent": dict(self.frequency_bands),
        }


def regime_error(residual_rad: FloatArray, mask: BoolArray) -> RegimeError:
    """Error of ``residual_rad`` (shape (n,)) over the samples in ``mask``."""
    r = np.asarray(residual_rad, dtype=float)
    total = float(np.sum(r * r))
    k = int(mask.sum())
    if k == 0:
        return RegimeError(0.0, 0.0, 0, 0.0)
    sq = float(np.sum(r[mask] ** 2))
    share = 100.0 * sq / total if total > 0 else 0.0
    return RegimeError(math.degrees(math.sqrt(sq / k)), share, k, k / r.size)


def _window_any(mask: BoolArray, k: int) -> BoolArray:
    """out[t] = any(mask[t−k..t]) (trailing window of k+1 samples)."""
    if k <= 0:
        return mask.copy()
    f = maximum_filter1d(mask.astype(np.uint8), size=k + 1, origin=k // 2, mode="nearest")
    out: BoolArray = f.astype(bool)
    return out


def _window_all(mask: BoolArray, k: int) -> BoolArray:
    """out[t] = all(mask[t−k..t])."""
    if k <= 0:
        return mask.copy()
    f = minimum_filter1d(mask.astype(np.uint8), size=k + 1, origin=k // 2, mode="nearest")
    out: BoolArray = f.astype(bool)
    return out


def regime_masks(
    omega_rad_s: FloatArray, alpha_rad_s2: FloatArray, dt_s: float, horizon_samples: int = 0
) -> dict[str, BoolArray]:
    """Boolean masks, shape (n,) each, of the samples whose prediction window is in each regime.

    ``horizon_samples`` is k of the k-step predictor (0 for free simulation: the sample itself).
    """
    w = np.asarray(omega_rad_s, dtype=float)
    a = np.asarray(alpha_rad_s2, dtype=float)
    aw = np.abs(w)
    w95 = float(np.percentile(aw, 95)) or 1.0
    a95 = float(np.percentile(np.abs(a), 95)) or 1.0
    hold_v = HOLD_SPEED_FRACTION * w95
    still = aw < hold_v
    span = max(1, int(round(REVERSAL_SPAN_S / dt_s)))
    moving_before = maximum_filter1d(aw, size=span + 1, origin=span // 2, mode="nearest") > hold_v
    moving_after = maximum_filter1d(aw, size=span + 1, origin=-((span + 1) // 2), mode="nearest") > hold_v
    sign_change = np.zeros(w.size, dtype=bool)
    sign_change[1:] = (w[1:] * w[:-1] < 0) | ((w[1:] == 0) & (w[:-1] != 0))
    reversal_pt = sign_change & moving_before & moving_after
    # A start: a hold of at least the reversal span followed by motion.
    held_long = minimum_filter1d(still.astype(np.uint8), size=span + 1, origin=span // 2, mode="nearest") > 0
    start_pt = np.zeros(w.size, dtype=bool)
    start_pt[1:] = held_long[:-1] & ~still[1:]
    k = int(horizon_samples)
    pad = max(1, k // 4)  # the reversal's own transient reaches a little past the sign change
    masks = {
        "reversal": _window_any(_spread(reversal_pt, pad), k),
        "start": _window_any(_spread(start_pt, pad), k),
        "hold": _window_all(still, k),
        "low_speed": _window_all(aw < LOW_SPEED_FRACTION * w95, k) & ~_window_all(still, k),
        "high_speed": _window_all(aw > HIGH_SPEED_FRACTION * w95, k),
        "high_accel": _window_any(np.abs(a) > HIGH_ACCEL_FRACTION * a95, k),
    }
    masks["moving"] = ~masks["hold"]
    return masks


def _spread(points: BoolArray, pad: int) -> BoolArray:
    """Mark ±pad samples around each True."""
    out: BoolArray = maximum_filter1d(points.astype(np.uint8), size=2 * pad + 1, mode="constant").astype(bool)
    return out


def _bins(
    residual: FloatArray, values: FloatArray, edges: FloatArray, unit: str
) -> tuple[tuple[str, RegimeError], ...]:
    out = []
    for i in range(edges.size - 1):
        lo, hi = edges[i], edges[i + 1]
        m = (values >= lo) & ((values < hi) if i < edges.size - 2 else (values <= hi))
        out.append((f"{lo:.3g}..{hi:.3g} {unit}", regime_error(residual, m)))
    return tuple(out)


def frequency_shares(residual: FloatArray, dt_s: float) -> tuple[tuple[str, float], ...]:
    """Share (%) of the residual's power in each band of :data:`FREQUENCY_BANDS_HZ`."""
    r = np.asarray(residual, dtype=float) - float(np.mean(residual))
    p = np.abs(np.fft.rfft(r)) ** 2
    f = np.fft.rfftfreq(r.size, dt_s)
    total = float(p[1:].sum()) or 1.0
    out = []
    for lo, hi in FREQUENCY_BANDS_HZ:
        if lo >= f[-1]:
            break
        sel = (f >= lo) & (f < hi) & (f > 0)
        label = f"{lo:g}-{hi:g} Hz" if math.isfinite(hi) else f">{lo:g} Hz"
        out.append((label, 100.0 * float(p[sel].sum()) / total))
    return tuple(out)


def break_down(
    residual_rad: FloatArray,
    theta_rad: FloatArray,
    omega_rad_s: FloatArray,
    alpha_rad_s2: FloatArray,
    t_s: FloatArray,
    horizon_samples: int = 0,
) -> RegimeBreakdown:
    """Break ``residual_rad`` (shape (n,)) down by regime, position, time and frequency."""
    dt = float(np.median(np.diff(t_s)))
    masks = regime_masks(omega_rad_s, alpha_rad_s2, dt, horizon_samples)
    regimes = {name: regime_error(residual_rad, masks[name]) for name in REGIME_NAMES}
    th = np.asarray(theta_rad, dtype=float)
    lo, hi = float(th.min()), float(th.max())
    pos = _bins(residual_rad, th, np.linspace(lo, hi if hi > lo else lo + 1e-9, POSITION_BINS + 1), "rad")
    tt = np.asarray(t_s, dtype=float)
    seg = _bins(residual_rad, tt, np.linspace(tt[0], tt[-1], TIME_SEGMENTS + 1), "s")
    return RegimeBreakdown(regimes, pos, seg, frequency_shares(residual_rad, dt))


__all__ = [
    "REGIME_NAMES",
    "RegimeBreakdown",
    "RegimeError",
    "break_down",
    "frequency_shares",
    "regime_error",
    "regime_masks",
]
