"""An axis model: the base model plus a set of effects, with every parameter in SI units."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from tracker.errors import ConfigError
from tracker.plant.effects import (
    BASE_EFFECTS,
    CATALOGUE,
    check_position_only,
    get_effect,
    get_param,
    is_generic,
)
from tracker.plant.params import AxisPreset, get_preset

if TYPE_CHECKING:
    import control


def _freeze(params: Mapping[str, float]) -> MappingProxyType[str, float]:
    return MappingProxyType(dict(params))


@dataclass(frozen=True, slots=True)
class AxisModel:
    """Base model J·θ'' = K·u − b·θ' − Fc·sign(θ') (seed eq. 3.2) plus effects.

    The drive's rail clips u (the rig's ±10 V amplifier; a log's own in the workbench:
    :func:`tracker.plant.effects.saturation.drive_rail_v`).

    ``effects`` lists the effects added to the base, in the order they were added.
    ``params`` holds every parameter of the base and of those effects, keyed
    ``"<effect>.<param>"``. Use :meth:`create` to build one with defaults filled in.
    """

    gain_nm_per_v: float
    effects: tuple[str, ...] = ()
    params: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))

    @classmethod
    def create(
        cls,
        gain_nm_per_v: float,
        base_params: Mapping[str, float],
        effects: Iterable[str] = (),
        overrides: Mapping[str, float] | None = None,
    ) -> AxisModel:
        """Build a validated model: catalogue defaults, then ``base_params``, then ``overrides``."""
        if not np.isfinite(gain_nm_per_v) or gain_nm_per_v <= 0:
            raise ConfigError(f"gain K must be a positive number, got {gain_nm_per_v!r}")
        names: list[str] = []
        for e in effects:
            e = e.strip()
            if not e or e in BASE_EFFECTS:
                continue
            get_effect(e)
            if e not in names:
                names.append(e)
        values: dict[str, float] = {}
        for effect_name in (*BASE_EFFECTS, *names):
            for p in CATALOGUE[effect_name].params:
                values[f"{effect_name}.{p.name}"] = p.default
        given = {**base_params, **(overrides or {})}
        values.update(base_params)
        # A newly added asymmetry starts symmetric (same as its positive-direction twin); a value
        # that is given is kept.
        for effect, twin in (("coulomb_asymmetry", "coulomb.torque"), ("viscous_asymmetry", "viscous.b")):
            if effect in names and f"{effect}.negative" not in given:
                values[f"{effect}.negative"] = values[twin]
        for key, v in (overrides or {}).items():
            if key.split(".")[0] not in (*BASE_EFFECTS, *names):
                raise ConfigError(f"parameter {key!r} belongs to an effect the model does not have")
            values[key] = v
        for key, v in values.items():
            values[key] = get_param(key).check(v, "model")
        for name in names:
            if is_generic(name):
                # The simulator tabulates a generic effect's torque at rest: it must not depend
                # on the velocity at these values either.
                check_position_only(CATALOGUE[name], values, "model")
        return cls(float(gain_nm_per_v), tuple(names), _freeze(values))

    @classmethod
    def for_axis(
        cls,
        axis: str | AxisPreset,
        effects: Iterable[str] = (),
        overrides: Mapping[str, float] | None = None,
        gain_nm_per_v: float | None = None,
    ) -> AxisModel:
        """The seed's model of ``axis`` ("pan"/"tilt") with ``effects`` added."""
        preset = get_preset(axis) if isinstance(axis, str) else axis
        gain = preset.gain_nm_per_v if gain_nm_per_v is None else gain_nm_per_v
        return cls.create(gain, preset.base_params(), effects, overrides)

    def has(self, effect: str) -> bool:
        """True when ``effect`` is in the base or has been added."""
        return effect in BASE_EFFECTS or effect in self.effects

    def with_effect(self, effect: str, overrides: Mapping[str, float] | None = None) -> AxisModel:
        """A new model with ``effect`` added (defaults for its parameters unless overridden)."""
        get_effect(effect)
        base = {k: v for k, v in self.params.items()}
        return AxisModel.create(self.gain_nm_per_v, base, (*self.effects, effect), overrides)

    def without_effect(self, effect: str) -> AxisModel:
        """A new model with ``effect`` removed."""
        keep = tuple(e for e in self.effects if e != effect)
        base = {k: v for k, v in self.params.items() if k.split(".")[0] != effect}
        return AxisModel.create(self.gain_nm_per_v, base, keep)

    def with_params(self, updates: Mapping[str, float]) -> AxisModel:
        """A new model with some parameter values replaced (validated against bounds)."""
        return AxisModel.create(self.gain_nm_per_v, dict(self.params), self.effects, updates)

    def free_param_names(self) -> tuple[str, ...]:
        """Parameters the fitter adjusts by default (``Param.fit``), in a stable order."""
        return tuple(k for k in self.params if get_param(k).fit)

    def linearised_tf(self) -> control.TransferFunction:
        """Linearised plant θ(s)/u(s) = (K/J) / (s² + (b/J)·s), Coulomb dropped (seed ch. 4)."""
        import control  # python-control takes a second to import; only this needs it

        j = self.params["inertia.J"]
        b = self.params["viscous.b"]
        return control.tf([self.gain_nm_per_v / j], [1.0, b / j, 0.0])

    def to_dict(self) -> dict[str, object]:
        """JSON-ready description."""
        return {
            "gain_nm_per_v": self.gain_nm_per_v,
            "effects": list(self.effects),
            "params": dict(self.params),
        }
