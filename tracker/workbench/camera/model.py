"""The camera model: a speed-commanded axis and the effects the workbench can add to it.

Base model (no effects): the measured angle moves at ``speed.per_step · step`` rad/s from the
moment a command is logged until the next one (a linear speed map, the same both ways). The
effects, each with its parameters (SI units, bounds):

=============== =========================================== =====================================
effect          parameters                                  physics
=============== =========================================== =====================================
latency         ``latency.seconds`` (s)                     a command acts this long after it is
                                                            logged (network, the camera's own
                                                            cycle, the age of the position reply)
speed_table     ``speed_table.positive.<k>``,               the speed of step k per direction
                ``speed_table.negative.<k>`` (rad/s)        (replaces the linear map)
acceleration    ``acceleration.limit`` (rad/s²)             the speed follows the command at most
                                                            this fast
backlash        ``backlash.width`` (rad, the whole play)    the measured angle stays put after a
                                                            reversal until the drive took up the play
quantization    ``quantization.step`` (rad)                 the reported angle is a whole number
                                                            of counts (a sensor effect: it changes
                                                            no prediction)
=============== =========================================== =====================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from tracker.errors import ConfigError

CAMERA_EFFECTS = ("latency", "speed_table", "acceleration", "backlash", "quantization")
EFFECT_TEXT = {
    "latency": "commands act later than they are logged",
    "speed_table": "the speed of each step follows a nonlinear table, per direction",
    "acceleration": "the speed follows a new command at a limited acceleration",
    "backlash": "the angle stays put after a reversal until the play is taken up",
    "quantization": "the reported angle is a whole number of counts",
}
LOOK_ALIKES = {
    "latency": ("acceleration",),
    "acceleration": ("latency",),
    "speed_table": (),
    "backlash": ("latency",),
    "quantization": (),
}
EXPERIMENTS = {
    "latency": "step the speed from rest and time the first count change: a latency delays it by the "
    "same time at every step; an acceleration limit delays it by less at higher steps",
    "acceleration": "step from rest to the fastest step and back: the rate ramps at the limit; a pure "
    "latency shows a jump after a dead time instead",
    "speed_table": "run `tracker camera speed-id`: every step in each direction, its steady rate",
    "backlash": "reverse at a slow step: the angle waits for the play; at a fast step it waits for "
    "less time, a latency waits the same time at every step",
    "quantization": "",
}
# (lower, upper) bounds of the parameters
BOUNDS = {
    "speed.per_step": (1e-6, 20.0),
    "speed_table": (1e-6, 50.0),
    "latency.seconds": (0.0, 1.0),
    "acceleration.limit": (0.01, math.inf),  # inf: reaches any speed at once
    "backlash.width": (0.0, 0.2),
    "quantization.step": (0.0, 0.1),
}
UNITS = {
    "speed.per_step": "rad/s",
    "speed_table": "rad/s",
    "latency.seconds": "s",
    "acceleration.limit": "rad/s²",
    "backlash.width": "rad",
    "quantization.step": "rad",
}
FloatArray = NDArray[np.float64]


def param_unit(name: str) -> str:
    """The unit of a parameter name."""
    return UNITS["speed_table" if name.startswith("speed_table.") else name]


def param_bounds(name: str) -> tuple[float, float]:
    """The bounds of a parameter name."""
    return BOUNDS["speed_table" if name.startswith("speed_table.") else name]


@dataclass(frozen=True, slots=True)
class CameraModel:
    """A speed-commanded camera axis (see the module docstring).

    ``table_positive_rad_s[k - 1]`` is the speed of step k toward positive angles (used with the
    ``speed_table`` effect; the base model uses ``per_step_rad_s · k``).
    """

    effects: tuple[str, ...] = ()
    per_step_rad_s: float = math.radians(2.0)
    table_positive_rad_s: tuple[float, ...] = ()
    table_negative_rad_s: tuple[float, ...] = ()
    latency_s: float = 0.0
    accel_rad_s2: float = math.radians(200.0)
    backlash_rad: float = 0.0
    quant_rad: float = 0.0
    n_steps: int = 24
    fixed: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        unknown = [e for e in self.effects if e not in CAMERA_EFFECTS]
        if unknown:
            raise ConfigError(
                f"unknown camera effect {', '.join(unknown)}; camera effects are {', '.join(CAMERA_EFFECTS)}"
            )
        if "speed_table" in self.effects:
            for name, table in (
                ("positive", self.table_positive_rad_s),
                ("negative", self.table_negative_rad_s),
            ):
                if len(table) != self.n_steps:
                    raise ConfigError(f"speed_table.{name} has {len(table)} steps, the model {self.n_steps}")

    @classmethod
    def base(cls, n_steps: int, effects: tuple[str, ...] = (), **values: float) -> CameraModel:
        """The base model for a log using steps up to ``n_steps``, with ``effects`` added."""
        model = cls(n_steps=max(1, int(n_steps)))
        for e in effects:
            model = model.with_effect(e)
        return model.with_params(values) if values else model

    def has(self, effect: str) -> bool:
        """True when ``effect`` is in the model."""
        return effect in self.effects

    def with_effect(self, effect: str) -> CameraModel:
        """The model with ``effect`` added at neutral starting values (the speed table starts
        as the linear map)."""
        if effect not in CAMERA_EFFECTS:
            raise ConfigError(
                f"unknown camera effect {effect!r}; camera effects are {', '.join(CAMERA_EFFECTS)}"
            )
        if effect in self.effects:
            return self
        effects = tuple(e for e in CAMERA_EFFECTS if e in self.effects or e == effect)
        extra: dict[str, object] = {}
        if effect == "speed_table":
            linear = tuple(self.per_step_rad_s * k for k in range(1, self.n_steps + 1))
            extra = {"table_positive_rad_s": linear, "table_negative_rad_s": linear}
        return replace(self, effects=effects, **extra)  # type: ignore[arg-type]

    def without_effect(self, effect: str) -> CameraModel:
        """The model without ``effect``."""
        return replace(self, effects=tuple(e for e in self.effects if e != effect))

    # -- the speed map -------------------------------------------------------------------------
    def speeds_rad_s(self, step: NDArray[np.int64]) -> FloatArray:
        """The signed speed (rad/s) each signed step commands. Shape of ``step``."""
        s = np.asarray(step, dtype=np.int64)
        if not self.has("speed_table"):
            return self.per_step_rad_s * s.astype(float)
        k = np.clip(np.abs(s), 1, self.n_steps) - 1
        pos = np.asarray(self.table_positive_rad_s)[k]
        neg = np.asarray(self.table_negative_rad_s)[k]
        return np.where(s > 0, pos, np.where(s < 0, -neg, 0.0))

    def table_rad_s(self, direction: int) -> FloatArray:
        """The speed of every step 1..n_steps in ``direction`` (+1/-1), whichever map the model has."""
        if not self.has("speed_table"):
            return self.per_step_rad_s * np.arange(1, self.n_steps + 1, dtype=float)
        return np.asarray(
            self.table_positive_rad_s if direction > 0 else self.table_negative_rad_s, dtype=float
        )

    # -- the parameters ------------------------------------------------------------------------
    @property
    def effective_accel_rad_s2(self) -> float:
        """The acceleration the simulation uses (infinite without the effect)."""
        return self.accel_rad_s2 if self.has("acceleration") else math.inf

    @property
    def effective_latency_s(self) -> float:
        return self.latency_s if self.has("latency") else 0.0

    @property
    def effective_backlash_rad(self) -> float:
        return self.backlash_rad if self.has("backlash") else 0.0

    def params(self) -> dict[str, float]:
        """Every parameter of the model by name (SI units)."""
        out: dict[str, float] = {}
        if self.has("speed_table"):
            for k in range(self.n_steps):
                out[f"speed_table.positive.{k + 1}"] = self.table_positive_rad_s[k]
            for k in range(self.n_steps):
                out[f"speed_table.negative.{k + 1}"] = self.table_negative_rad_s[k]
        else:
            out["speed.per_step"] = self.per_step_rad_s
        if self.has("latency"):
            out["latency.seconds"] = self.latency_s
        if self.has("acceleration"):
            out["acceleration.limit"] = self.accel_rad_s2
        if self.has("backlash"):
            out["backlash.width"] = self.backlash_rad
        if self.has("quantization"):
            out["quantization.step"] = self.quant_rad
        return out

    def with_params(self, values: dict[str, float]) -> CameraModel:
        """The model with some parameters replaced (ConfigError naming an unknown or out-of-bounds one)."""
        pos, neg = list(self.table_positive_rad_s), list(self.table_negative_rad_s)
        fields: dict[str, float] = {}
        simple = {
            "speed.per_step": "per_step_rad_s",
            "latency.seconds": "latency_s",
            "acceleration.limit": "accel_rad_s2",
            "backlash.width": "backlash_rad",
            "quantization.step": "quant_rad",
        }
        for name, value in values.items():
            v = float(value)
            if name.startswith("speed_table."):
                _, direction, k_text = (name.split(".") + ["", ""])[:3]
                if (
                    not self.has("speed_table")
                    or direction not in ("positive", "negative")
                    or not k_text.isdigit()
                    or not 1 <= int(k_text) <= self.n_steps
                ):
                    raise ConfigError(
                        f"{name!r} is not a parameter of this camera model (steps 1..{self.n_steps}"
                        f"{'' if self.has('speed_table') else ', and it has no speed_table'})"
                    )
                lo, hi = BOUNDS["speed_table"]
                if not (math.isfinite(v) and lo <= v <= hi):
                    raise ConfigError(f"{name} = {v!r} rad/s is outside [{lo:g}, {hi:g}]")
                (pos if direction == "positive" else neg)[int(k_text) - 1] = v
                continue
            if name not in simple:
                raise ConfigError(
                    f"{name!r} is not a camera model parameter; they are "
                    f"{', '.join([*simple, 'speed_table.positive.K', 'speed_table.negative.K'])}"
                )
            lo, hi = BOUNDS[name]
            if math.isnan(v) or not lo <= v <= hi or (math.isinf(v) and name != "acceleration.limit"):
                raise ConfigError(f"{name} = {v!r} {UNITS[name]} is outside [{lo:g}, {hi:g}]")
            fields[simple[name]] = v
        return replace(self, table_positive_rad_s=tuple(pos), table_negative_rad_s=tuple(neg), **fields)  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: effects, parameters, step count."""
        return {
            "kind": "camera",
            "effects": list(self.effects),
            "n_steps": self.n_steps,
            "params": self.params(),
        }
