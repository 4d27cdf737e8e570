"""k-step prediction of a camera log and the compare result: fit %, RMS, error by regime.

Every row's angle is predicted from the angle measured k rows earlier plus the model's motion
over those k command periods: ``θ̂_i = θ_{i−k} + (φ_i − φ_{i−k})`` with φ the model's angle
along the whole log (:mod:`simulate`). A speed-commanded axis needs no estimated state: its
speed is a function of the commands alone, so the prediction is the model's motion since a
measured anchor (a latency, an acceleration ramp or the play of a backlash reach back before the
window through φ). The fit % is MATLAB's on what had to be predicted, the increment
``θ_i − θ_{i−k}`` (the sensitive number, as ``fit_percent_increment`` for a DC log).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tracker.errors import DataError
from tracker.workbench.camera.log import CameraLog
from tracker.workbench.camera.model import CameraModel
from tracker.workbench.camera.simulate import model_angles

FloatArray = NDArray[np.float64]
DEFAULT_HORIZON_S = 0.5
REGIMES = ("reversal", "start", "stop", "speed_change", "steady")


def horizon_rows(log: CameraLog, horizon_s: float | None) -> int:
    """The horizon in rows (at least 1; DataError when it leaves fewer than half the rows)."""
    h = DEFAULT_HORIZON_S if horizon_s is None else float(horizon_s)
    if not (math.isfinite(h) and h > 0):
        raise DataError(f"horizon {horizon_s!r} s must be a positive number")
    k = max(1, int(round(h / log.period_s)))
    if k > log.n // 2:
        raise DataError(f"horizon {h:g} s is {k} rows: longer than half the log ({log.n} rows)")
    return k


def increment_errors(log: CameraLog, model: CameraModel, k: int) -> FloatArray:
    """Measured minus predicted increment over k rows, for rows k..n-1 (rad, shape (n-k,))."""
    phi = model_angles(log, model)
    return (log.theta_rad[k:] - log.theta_rad[:-k]) - (phi[k:] - phi[:-k])


def fit_percent(err: FloatArray, target: FloatArray) -> float:
    """MATLAB's fit: 100·(1 − ‖err‖/‖target − mean target‖)."""
    denom = float(np.linalg.norm(target - np.mean(target)))
    return 100.0 * (1.0 - float(np.linalg.norm(err)) / denom) if denom > 0 else -math.inf


def window_regimes(log: CameraLog, k: int) -> dict[str, NDArray[np.bool_]]:
    """For each prediction (row i = k..n-1), what the commands did in its window (i−k, i]:
    a reversal, a start from stop, a stop, another speed change, or nothing (steady)."""
    s = log.step
    prev, cur = s[:-1], s[1:]
    rev = (prev * cur) < 0
    start = (prev == 0) & (cur != 0)
    stop = (prev != 0) & (cur == 0)
    change = (prev != cur) & ~rev & ~start & ~stop
    out: dict[str, NDArray[np.bool_]] = {}
    taken = np.zeros(log.n - k, dtype=bool)
    # event e at transition j -> j+1 (row j+1) falls in the window of rows i with i-k < j+1 <= i
    for name, ev in (("reversal", rev), ("start", start), ("stop", stop), ("speed_change", change)):
        c = np.concatenate(([0], np.cumsum(ev.astype(np.int64))))  # c[i] = events at rows <= i
        rows = np.arange(k, log.n)
        hit = (c[rows] - c[rows - k]) > 0
        out[name] = hit & ~taken
        taken |= hit
    out["steady"] = ~taken
    return out


@dataclass(frozen=True, slots=True)
class RegimeShare:
    """How much of the error one regime holds."""

    fraction_of_time: float
    share_of_error_percent: float
    concentration: float
    rms_deg: float


@dataclass(frozen=True, slots=True)
class CameraCompareResult:
    """A camera model against a camera log (k-step prediction)."""

    fit_percent_increment: float
    fit_percent: float
    rms_deg: float
    horizon_s: float
    horizon_rows: int
    period_s: float
    quantization_floor_deg: float
    regimes: dict[str, RegimeShare]
    errors_rad: FloatArray = field(repr=False)
    model: CameraModel = field(repr=False)

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": "camera",
            "fit_percent_increment": self.fit_percent_increment,
            "fit_percent": self.fit_percent,
            "rms_deg": self.rms_deg,
            "horizon_s": self.horizon_s,
            "horizon_rows": self.horizon_rows,
            "command_period_s": self.period_s,
            "quantization_floor_deg": self.quantization_floor_deg,
            "regimes": {
                k: {
                    "fraction_of_time": r.fraction_of_time,
                    "share_of_error_percent": r.share_of_error_percent,
                    "concentration": r.concentration,
                    "rms_deg": r.rms_deg,
                }
                for k, r in self.regimes.items()
            },
            "model": self.model.to_dict(),
        }


def count_step_rad(log: CameraLog) -> float:
    """The reported angle's count (rad): the smallest change that the others are multiples
    of, 0 when the angle looks continuous."""
    d = np.abs(np.diff(log.theta_rad))
    d = d[d > 1e-12]
    if d.size < 10:
        return 0.0
    smallest = float(np.min(d))
    for parts in range(1, 11):  # the smallest change may be several counts (a fast log)
        q = smallest / parts
        off = np.abs(d / q - np.round(d / q))
        if np.median(off) < 0.02 and np.max(off) < 0.2:
            return q
    return 0.0


def compare_camera(log: CameraLog, model: CameraModel, horizon_s: float | None = None) -> CameraCompareResult:
    """How well ``model`` predicts ``log`` k rows ahead (see the module docstring)."""
    k = horizon_rows(log, horizon_s)
    err = increment_errors(log, model, k)
    inc = log.theta_rad[k:] - log.theta_rad[:-k]
    y = log.theta_rad[k:]
    total = float(np.sum(err**2))
    regimes = {}
    for name, mask in window_regimes(log, k).items():
        frac = float(np.mean(mask))
        share = 100.0 * float(np.sum(err[mask] ** 2)) / total if total > 0 else 0.0
        rms = math.degrees(float(np.sqrt(np.mean(err[mask] ** 2)))) if mask.any() else 0.0
        regimes[name] = RegimeShare(frac, share, share / (100.0 * frac) if frac > 0 else 0.0, rms)
    q = count_step_rad(log)
    return CameraCompareResult(
        fit_percent_increment=fit_percent(err, inc),
        fit_percent=fit_percent(err, y),
        rms_deg=math.degrees(float(np.sqrt(np.mean(err**2)))),
        horizon_s=k * log.period_s,
        horizon_rows=k,
        period_s=log.period_s,
        quantization_floor_deg=math.degrees(q / math.sqrt(6.0)),
        regimes=regimes,
        errors_rad=err,
        model=model,
    )
