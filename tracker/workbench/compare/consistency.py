"""Is a model's residual what a right model leaves on this run? The verdict against the simulated band.

The measured k-step residual is set against :func:`~tracker.workbench.compare.floor.residual_floor`
(replicas made by the fitted model itself, read through the log's sensor, with the same
pipeline). Two numbers, each with a one-sided 99 % prediction bound from the R replicas
(Student's t with R − 1 degrees of freedom: mean + t·s·√(1 + 1/R)):

* the residual **RMS** — a missing effect adds error that neither the sensor nor the run's load
  disturbance explains — over the record and in each regime (the measured run's regime masks),
  so a wrong model that shows only at reversals or at speed is caught and named;
* its **correlation length** Σ_{τ=1..M} r(τ) (in samples), with the replicas' autocorrelation
  envelope to draw: reported, not a gate, because its value depends on the disturbance's
  spectrum, which the log gives less well than its power.

The residual is *consistent* when every RMS is inside its bound; the bounds share the 1 % false
alarm rate (Bonferroni over the record and the regimes judged). Nothing here is tuned to a case:
the bounds come only from the replicas' spread.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import t as student_t

from tracker.workbench.compare.floor import ResidualFloor
from tracker.workbench.compare.regimes import regime_masks
from tracker.workbench.compare.residuals import autocorrelation
from tracker.workbench.measurements.states import StateEstimate

FloatArray = NDArray[np.float64]

CONFIDENCE = 0.99
# A regime with fewer samples than this says too little to be judged on its own.
MIN_REGIME_SAMPLES = 200


def upper_bound(samples: FloatArray, confidence: float = CONFIDENCE) -> float:
    """One-sided prediction bound of one more draw: mean + t_{conf, R−1}·s·√(1 + 1/R)."""
    x = np.asarray(samples, dtype=float)
    r = x.size
    if r < 2:
        return math.inf
    s = float(np.std(x, ddof=1))
    return float(np.mean(x)) + float(student_t.ppf(confidence, r - 1)) * s * math.sqrt(1.0 + 1.0 / r)


def correlation_length(r: FloatArray) -> float:
    """Σ_{τ≥1} r(τ) of an autocorrelation r (r[0] = 1), in samples."""
    return float(np.sum(np.asarray(r, dtype=float)[1:]))


@dataclass(frozen=True, slots=True)
class Check:
    """One measured figure against what a right model gives (replicas' mean and upper bound)."""

    measured: float
    expected: float
    bound: float

    @property
    def ok(self) -> bool:
        return self.measured <= self.bound

    @property
    def ratio(self) -> float:
        """Measured ÷ expected (1 = exactly what a right model leaves)."""
        return self.measured / self.expected if self.expected > 0 else math.inf

    def to_dict(self) -> dict[str, object]:
        return {
            "measured": self.measured,
            "expected": self.expected,
            "bound": self.bound,
            "ratio": self.ratio,
            "ok": self.ok,
        }


@dataclass(frozen=True, slots=True)
class ResidualVerdict:
    """The residual of a model judged against the simulated band (overall and per regime).

    ``rms_rad`` and ``correlation_samples`` are the overall checks; ``regimes`` the RMS check of
    each regime with enough samples; ``autocorr_band`` shape (2, M+1): the replicas' lowest and
    highest autocorrelation per lag (to draw); ``floor`` the replicas themselves.
    """

    rms_rad: Check
    correlation_samples: Check
    regimes: Mapping[str, Check]
    autocorr_band: FloatArray
    floor: ResidualFloor

    @property
    def consistent(self) -> bool:
        """The residual is what a right model leaves: its RMS within the band, overall and in
        every regime judged."""
        return self.rms_rad.ok and not self.failing_regimes

    @property
    def failing_regimes(self) -> list[str]:
        return [name for name, c in self.regimes.items() if not c.ok]

    def explanation(self) -> str:
        """Why, in words with numbers."""
        rms, cor = self.rms_rad, self.correlation_samples
        q = self.floor.sensor
        parts = []
        if q.encoder_step_rad > 0:
            parts.append(f"encoder step {q.encoder_step_rad:.3g} rad")
        if q.white_noise_rad > 0:
            parts.append(f"noise {q.white_noise_rad:.3g} rad")
        if self.floor.disturbance_rms_nm > 0:
            parts.append(f"load disturbance {self.floor.disturbance_rms_nm:.3g} N·m RMS")
        size = (
            f"residual RMS {rms.measured:.3g} rad is {rms.ratio:.2f}× what the model itself leaves "
            f"on this run ({', '.join(parts) or 'a noiseless sensor'}; {self.floor.replicas} "
            f"simulated replicas: {rms.expected:.3g} rad, bound {rms.bound:.3g})"
        )
        corr = f"correlation length {cor.measured:.1f} samples (right model: {cor.expected:.1f})"
        if self.consistent:
            return f"Consistent with a right model: {size}; every regime within its band; {corr}."
        where = (
            " Above the band at: "
            + ", ".join(f"{n} ({self.regimes[n].ratio:.2f}×)" for n in self.failing_regimes)
            + "."
            if self.failing_regimes
            else ""
        )
        return f"Not what a right model leaves: {size}.{where} ({corr})"

    def to_dict(self, arrays: bool = False) -> dict[str, object]:
        out: dict[str, object] = {
            "consistent": self.consistent,
            "explanation": self.explanation(),
            "rms_rad": self.rms_rad.to_dict(),
            "correlation_samples": self.correlation_samples.to_dict(),
            "regimes": {k: v.to_dict() for k, v in self.regimes.items()},
            "failing_regimes": self.failing_regimes,
            "replicas": self.floor.replicas,
            "refitted": self.floor.refitted,
            "encoder_step_rad": self.floor.sensor.encoder_step_rad,
            "white_noise_rad": self.floor.sensor.white_noise_rad,
            "sensor_floor_rad": self.floor.sensor.floor_rad,
            "disturbance_rms_nm": self.floor.disturbance_rms_nm,
        }
        if arrays:
            out["autocorr_band_low"] = self.autocorr_band[0].tolist()
            out["autocorr_band_high"] = self.autocorr_band[1].tolist()
        return out


def judge_residual(
    residual_rad: FloatArray, est: StateEstimate, k: int, floor: ResidualFloor
) -> ResidualVerdict:
    """Judge a measured k-step residual (shape (n,)) against ``floor`` (same run, same k)."""
    e = np.asarray(residual_rad, dtype=float)[k:]
    max_lag = floor.autocorr.shape[1] - 1
    r = autocorrelation(e, max_lag)
    masks = regime_masks(est.omega_rad_s, est.alpha_rad_s2, est.dt_s, k)
    judged = [name for name in floor.regime_rms_rad if int(masks[name][k:].sum()) >= MIN_REGIME_SAMPLES]
    conf = 1.0 - (1.0 - CONFIDENCE) / (1 + len(judged))
    rms = Check(
        float(np.sqrt(np.mean(e**2))), float(np.mean(floor.rms_rad)), upper_bound(floor.rms_rad, conf)
    )
    lengths = np.array([correlation_length(a) for a in floor.autocorr])
    cor = Check(correlation_length(r), float(np.mean(lengths)), upper_bound(lengths, conf))
    regimes: dict[str, Check] = {}
    for name in judged:
        sel = masks[name][k:]
        reps = floor.regime_rms_rad[name]
        regimes[name] = Check(
            float(np.sqrt(np.mean(e[sel] ** 2))), float(np.mean(reps)), upper_bound(reps, conf)
        )
    band = np.vstack([floor.autocorr.min(axis=0), floor.autocorr.max(axis=0)])
    return ResidualVerdict(rms, cor, regimes, band, floor)


def agreement(verdict: ResidualVerdict, missing_effect: str | None) -> str:
    """How the residual verdict and the diagnosis (``missing_effect``, None: nothing) fit together."""
    if verdict.consistent and missing_effect is None:
        return (
            "The residual test and the diagnosis agree: nothing is missing. The error left is what "
            "the sensor and the run's load disturbance leave a right model."
        )
    if not verdict.consistent and missing_effect is not None:
        return (
            f"The residual test and the diagnosis agree: the residual is above what a right model "
            f"leaves, and the diagnosis names {missing_effect}."
        )
    if not verdict.consistent:
        return (
            "They differ, for a reason: the residual is above what a right model leaves "
            f"({verdict.rms_rad.ratio:.2f}×), but no effect of the catalogue removes it on held-out "
            "data. Suspect an effect outside the catalogue (see 'Your own effect') or a disturbance "
            "that depends on the state."
        )
    return (
        f"They differ, for a reason: adding {missing_effect} improves the held-out prediction, but "
        "the residual is already within the band a right model leaves on this run: the effect is "
        "real but small next to the sensor's floor here; a run that excites it more will show it."
    )


__all__ = ["Check", "agreement", "ResidualVerdict", "correlation_length", "judge_residual", "upper_bound"]
