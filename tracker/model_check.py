"""Check a model offered to an axis's controller against that axis's recent motion.

The engine keeps the last ``RECENT_S`` of (t, u, θ) of each axis (:class:`tracker.recording.RecentLog`).
Before :meth:`tracker.engine.Engine.set_model` replaces the controller's model, the candidate
must predict that motion: the workbench's k-step comparison
(:func:`tracker.workbench.compare.compare.compare_model`, horizon ``DEFAULT_HORIZON_S`` = 30 ms)
gives the RMS error X of the candidate and Y of the current model on the same states.

The limit Z is what the current model would score with its inertia off by a factor of two
(the smaller of ×2 and ×½): a candidate must predict better than that, or at least as well
as the current model (``accepted`` = X ≤ max(Y, Z)). The scale thus comes from the motion
itself: on the engine's own runs (docs/control.md) pan models with a fifth of the inertia
score 6–7× Z and are refused, inertia ×0.6 is refused, ×0.7 to ×1.5 (or Coulomb friction
±25 %) stays under Z; belt models on the rigid rig score 1.5–25× Z, a model of the rig's own
belt 0.06× Z, one 10 % off in frequency 1.6–3.4× Z.

When the recent motion cannot tell models apart (the axis held still: the RMS of its moves
over the horizon is under ``MIN_MOTION_RAD``, or there are fewer samples than a log needs) the
check is not *judged*. A
rigid model is then accepted with a note: there is nothing to contradict it, and the rigid
soft-limit guard does not rely on it (:mod:`tracker.control.envelope`). A model with a belt
(``compliance``) is refused: the belt guard (:mod:`tracker.control.belt_guard`) *does* rely on
it — a 9.4 Hz belt on a model with a fifth of the inertia, on the rigid seed rig, drove pan to
95.8° at a step to −89° — so it must first be confirmed by motion.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from tracker.errors import ConfigError, DataError
from tracker.plant.model import AxisModel
from tracker.workbench.compare.compare import DEFAULT_HORIZON_S, compare_model, horizon_samples
from tracker.workbench.measurements.data import Measurement
from tracker.workbench.measurements.states import estimate_states

# Seconds of recent motion the engine keeps per axis and checks models against.
RECENT_S = 10.0
# The current model's inertia is scaled by these to set the limit.
INERTIA_FACTORS = (2.0, 0.5)
# Below this RMS of the encoder's moves over the horizon (rad; 1.6 of the seed's counts) the
# axis held still and its recent motion does not tell models apart.
MIN_MOTION_RAD = 3e-4


@dataclass(frozen=True, slots=True)
class ModelCheck:
    """The figures of one check (rad, s). ``judged`` False: the motion could not tell."""

    axis: str
    judged: bool
    window_s: float
    horizon_s: float
    candidate_rms_rad: float
    current_rms_rad: float
    limit_rad: float
    motion_rms_rad: float = math.nan
    note: str = ""
    needs_judgement: bool = False

    @property
    def accepted(self) -> bool:
        """Judged: the candidate predicts no worse than the limit or the current model. Not
        judged: accepted unless ``needs_judgement`` (a model with a belt, which the belt guard
        trusts)."""
        if not self.judged:
            return not self.needs_judgement
        return self.candidate_rms_rad <= max(self.limit_rad, self.current_rms_rad)

    def describe(self) -> str:
        """The verdict with its figures, in degrees (e.g. after "pan model refused: ")."""
        if not self.judged and self.needs_judgement:
            return (
                "it has a belt, which the soft-limit guard trusts (tracker.control.belt_guard), and "
                f"it could not be checked: {self.note}"
            )
        if not self.judged:
            return f"not checked: {self.note}"
        verdict = "it predicts" if self.accepted else "it does not predict"
        return (
            f"{verdict} the last {self.window_s:.1f} s of {self.axis}: k-step "
            f"({1000 * self.horizon_s:.0f} ms) RMS error {math.degrees(self.candidate_rms_rad):.4f}°, "
            f"the current model {math.degrees(self.current_rms_rad):.4f}°; limit "
            f"{math.degrees(self.limit_rad):.4f}° (the current model with its inertia off by 2×)"
        )

    @classmethod
    def from_dict(cls, figures: Mapping[str, object]) -> ModelCheck:
        """The check back from :meth:`to_dict` (e.g. from a worker process)."""

        def num(key: str) -> float:
            value = figures[key]
            if not isinstance(value, int | float):
                raise ConfigError(f"model check figure {key!r} is {value!r}, not a number")
            return float(value)

        return cls(
            str(figures["axis"]),
            bool(figures["judged"]),
            num("window_s"),
            num("horizon_s"),
            num("candidate_rms_rad"),
            num("current_rms_rad"),
            num("limit_rad"),
            num("motion_rms_rad"),
            str(figures["note"]),
            bool(figures["needs_judgement"]),
        )

    def to_dict(self) -> dict[str, object]:
        """JSON-ready figures (SI units)."""
        return {
            "axis": self.axis,
            "judged": self.judged,
            "accepted": self.accepted,
            "window_s": self.window_s,
            "horizon_s": self.horizon_s,
            "candidate_rms_rad": self.candidate_rms_rad,
            "current_rms_rad": self.current_rms_rad,
            "limit_rad": self.limit_rad,
            "motion_rms_rad": self.motion_rms_rad,
            "note": self.note,
            "needs_judgement": self.needs_judgement,
        }


def check_model(
    axis: str,
    recent: Measurement | None,
    candidate: AxisModel,
    current: AxisModel,
    horizon_s: float = DEFAULT_HORIZON_S,
) -> ModelCheck:
    """Does ``candidate`` predict ``recent`` (the axis's last seconds) as the module docstring asks?

    Parameters
    ----------
    axis : the axis name (for the figures and messages).
    recent : the recent log (t s, u V, θ rad, shape (n,) each), or None when there is none yet.
    candidate, current : the model offered and the one the controller uses now.
    horizon_s : the k-step prediction horizon (s).

    Returns
    -------
    ModelCheck
    """
    belt = candidate.has("compliance")
    nan = math.nan
    if recent is None:
        return ModelCheck(axis, False, 0.0, horizon_s, nan, nan, nan, nan, "no recent motion recorded", belt)
    window_s = recent.n * recent.dt_s
    try:
        k = horizon_samples(horizon_s, recent.dt_s, recent.n)
    except DataError as exc:  # too short for the horizon
        return ModelCheck(axis, False, window_s, horizon_s, nan, nan, nan, nan, str(exc), belt)
    theta = recent.theta_rad
    motion = float(np.sqrt(np.mean((theta[k:] - theta[:-k]) ** 2)))
    if motion < MIN_MOTION_RAD:
        note = (
            f"the last {window_s:.1f} s of {axis} do not tell models apart (the axis held still); "
            "move the axis and offer the model again to have it checked"
        )
        return ModelCheck(axis, False, window_s, horizon_s, nan, nan, nan, motion, note, belt)
    states = estimate_states(recent)
    x = compare_model(recent, candidate, horizon_s, states=states).rms_rad
    y = compare_model(recent, current, horizon_s, states=states).rms_rad
    z = min(
        compare_model(recent, _with_inertia(current, f), horizon_s, states=states).rms_rad
        for f in INERTIA_FACTORS
    )
    x = x if math.isfinite(x) else math.inf  # a prediction that blows up predicts nothing
    if not (math.isfinite(y) and math.isfinite(z)):
        note = "the current model's prediction is not finite"
        return ModelCheck(axis, False, window_s, horizon_s, x, y, z, motion, note, belt)
    return ModelCheck(axis, True, window_s, horizon_s, x, y, z, motion, "", belt)


def _with_inertia(model: AxisModel, factor: float) -> AxisModel:
    return model.with_params({"inertia.J": model.params["inertia.J"] * factor})
