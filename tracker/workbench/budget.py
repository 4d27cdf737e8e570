"""The error budget of a model version: how much of its error is the sensor, how much each added
effect removed, and how much is left for the model to explain ("how close to done").

Independent errors add in power, so the budget splits mean squares, not RMS values. For version
n of a history whose first version had the k-step mean-square error E₁:

    E₁ = floor² + Σ_{k=2..n} (E_{k−1} − E_k) + (E_n − floor²)
         sensor    explained by each change       left above the floor

``floor`` is the RMS a right model leaves on this run (the replicas of
:func:`~tracker.workbench.compare.floor.residual_floor`: sensor, load disturbance, refitting);
its sensor part (quantization and noise, read from the log) comes from replicas without the
disturbance and without refitting, split between quantization (step²/12) and white noise in
proportion to one reading's variance. "Left" below zero is the floor's own scatter: the model
is done for this run.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from tracker.plant.model import AxisModel
from tracker.workbench.compare.compare import DEFAULT_REPLICAS, CompareResult, compare_model, horizon_samples
from tracker.workbench.compare.floor import residual_floor
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.states import estimate_states, with_load_observer


@dataclass(frozen=True, slots=True)
class ErrorBudget:
    """One version's error split into what the sensor, each change and the model leave (deg).

    ``rms_deg``: the version's k-step RMS (over the samples the residual test judges).
    ``floor_deg``: what a right model leaves here; ``quantization_deg`` + ``noise_deg`` (in
    power) is its sensor part, ``disturbance_deg`` the rest (load disturbance, refitting).
    ``explained``: (change, RMS-equivalent deg = √(E_{k−1} − E_k), signed) for each change
    since version 1, oldest first. ``left_deg``: √(E_n − floor²), 0 at or below the floor.
    ``consistent``: the residual test's verdict (within the band of a right model).
    """

    rms_deg: float
    floor_deg: float
    quantization_deg: float
    noise_deg: float
    disturbance_deg: float
    explained: tuple[tuple[str, float], ...]
    left_deg: float
    consistent: bool

    @property
    def sensor_deg(self) -> float:
        return math.hypot(self.quantization_deg, self.noise_deg)

    @property
    def at_floor(self) -> bool:
        """Nothing is left for the model: the error is what a right model leaves here."""
        return self.consistent or self.left_deg <= 0.0

    def rebased(self, floor: ErrorBudget) -> ErrorBudget:
        """This version's budget against the floor of another version of the same run (the
        newest): the floor belongs to the run, but a wrong model's residual test reads part of
        its own error as disturbance, so an early version's floor runs high."""
        return dataclasses.replace(
            self,
            floor_deg=floor.floor_deg,
            quantization_deg=floor.quantization_deg,
            noise_deg=floor.noise_deg,
            disturbance_deg=floor.disturbance_deg,
            left_deg=math.sqrt(max(self.rms_deg**2 - floor.floor_deg**2, 0.0)),
        )

    def segments_deg2(self) -> list[tuple[str, float]]:
        """The stacked bar, bottom to top: (label, mean square deg²), all ≥ 0 except an
        explained part a change made worse (negative)."""
        out = [
            ("quantization", self.quantization_deg**2),
            ("noise", self.noise_deg**2),
            ("load disturbance", self.disturbance_deg**2),
        ]
        out += [(f"explained by {c}", math.copysign(d * d, d)) for c, d in self.explained]
        out.append(("left", self.left_deg**2))
        return out

    def to_dict(self) -> dict[str, object]:
        return {
            "rms_deg": self.rms_deg,
            "floor_deg": self.floor_deg,
            "sensor_deg": self.sensor_deg,
            "quantization_deg": self.quantization_deg,
            "noise_deg": self.noise_deg,
            "disturbance_deg": self.disturbance_deg,
            "explained": [{"change": c, "deg": d} for c, d in self.explained],
            "left_deg": self.left_deg,
            "consistent": self.consistent,
            "at_floor": self.at_floor,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, object]) -> ErrorBudget:
        """Rebuild from :meth:`to_dict` (KeyError/TypeError/ValueError on a bad record)."""
        ex = d.get("explained") or []
        assert isinstance(ex, list)
        return cls(
            float(d["rms_deg"]),  # type: ignore[arg-type]
            float(d["floor_deg"]),  # type: ignore[arg-type]
            float(d["quantization_deg"]),  # type: ignore[arg-type]
            float(d["noise_deg"]),  # type: ignore[arg-type]
            float(d["disturbance_deg"]),  # type: ignore[arg-type]
            tuple((str(e["change"]), float(e["deg"])) for e in ex),
            float(d["left_deg"]),  # type: ignore[arg-type]
            bool(d.get("consistent", False)),
        )

    def describe(self) -> list[str]:
        """The budget as text lines (RMS-equivalent degrees; shares of version 1's squared error)."""
        total = self.floor_deg**2 + sum(math.copysign(d * d, d) for _, d in self.explained)
        total += self.left_deg**2
        total = total if total > 0 else 1.0

        def share(deg: float) -> str:
            return f"{100 * math.copysign(deg * deg, deg) / total:5.1f} %"

        lines = [
            f"  floor (a right model on this run): {self.floor_deg:.4g} deg  {share(self.floor_deg)}",
            f"    sensor: quantization {self.quantization_deg:.3g}, noise {self.noise_deg:.3g}; "
            f"load disturbance and refit {self.disturbance_deg:.3g}",
        ]
        for change, d in self.explained:
            lines.append(f"  explained by {change:<22}: {d:.4g} deg  {share(d)}")
        if self.at_floor:
            lines.append(
                f"  left above the floor: none ({self.left_deg:.3g} deg, within the floor's scatter): "
                "the model is done for this run"
            )
        else:
            lines.append(f"  left above the floor: {self.left_deg:.4g} deg  {share(self.left_deg)}")
        lines.append("  (shares of version 1's squared error; RMS values are √ of each part)")
        return lines


def _signed_root(x: float) -> float:
    return math.copysign(math.sqrt(abs(x)), x)


def error_budget(
    meas: Measurement,
    model: AxisModel,
    earlier: Sequence[tuple[str, float]] = (),
    change: str = "",
    horizon_s: float | None = None,
    replicas: int = DEFAULT_REPLICAS,
    compared: CompareResult | None = None,
) -> ErrorBudget | None:
    """The budget of ``model`` on ``meas``.

    ``earlier``: (change, budget RMS deg) of the versions before this one, oldest first (the
    first one's change is not used); ``change`` is what made this version. ``compared``: the
    k-step comparison of ``model`` on ``meas`` with its residual test, when already made.
    Costs a residual test (``replicas`` refitted replicas) and two sensor-only replicas.
    None when the residual test has nothing to judge against (a log no physical axis could
    make: the replicas' refit leaves the parameter bounds).
    """
    res = compared
    if res is None or res.verdict is None:
        res = compare_model(meas, model, horizon_s=horizon_s, replicas=max(replicas, 2))
    v = res.verdict
    if v is None:
        return None
    k = horizon_samples(res.horizon_s, meas.dt_s, meas.n)
    est = with_load_observer(estimate_states(meas, model), model, meas)
    sensor = residual_floor(meas, model, est, k, 5, replicas=2, refit=False, disturbance=False, seed=7)
    rms = math.degrees(v.rms_rad.measured)
    floor = math.degrees(v.rms_rad.expected)
    sensor_deg = min(math.degrees(float(np.mean(sensor.rms_rad))), floor)
    q2 = sensor.sensor.encoder_step_rad**2 / 12.0
    w2 = sensor.sensor.white_noise_rad**2
    qshare = q2 / (q2 + w2) if q2 + w2 > 0 else 1.0
    chain = [*earlier, (change, rms)]
    explained = tuple(
        (c, _signed_root(prev**2 - now**2)) for (_, prev), (c, now) in zip(chain, chain[1:], strict=False)
    )
    return ErrorBudget(
        rms_deg=rms,
        floor_deg=floor,
        quantization_deg=sensor_deg * math.sqrt(qshare),
        noise_deg=sensor_deg * math.sqrt(1.0 - qshare),
        disturbance_deg=math.sqrt(max(floor**2 - sensor_deg**2, 0.0)),
        explained=explained,
        left_deg=math.sqrt(max(rms**2 - floor**2, 0.0)),
        consistent=v.consistent,
    )


__all__ = ["ErrorBudget", "error_budget"]
