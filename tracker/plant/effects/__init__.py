"""The catalogue of physical effects of an axis, read by the simulator, the fitter and the diagnosis.

Adding an effect is adding one module here with an ``EFFECT`` and listing it below (and, if it
is not a pure torque, teaching ``tracker.plant.simulate`` how it acts).
"""

from __future__ import annotations

from tracker.errors import ConfigError
from tracker.plant.effects import (
    backlash,
    compliance,
    coulomb,
    coulomb_asymmetry,
    delay,
    gravity,
    inertia,
    offset,
    quantization,
    ripple,
    saturation,
    stiction,
    viscous,
    viscous_asymmetry,
)
from tracker.plant.effects.base import Effect, Param

BASE_EFFECTS: tuple[str, ...] = ("inertia", "viscous", "coulomb")

CATALOGUE: dict[str, Effect] = {
    m.EFFECT.name: m.EFFECT
    for m in (
        inertia,
        viscous,
        coulomb,
        coulomb_asymmetry,
        viscous_asymmetry,
        offset,
        stiction,
        gravity,
        delay,
        saturation,
        ripple,
        backlash,
        compliance,
        quantization,
    )
}

# Effects a model can be missing (what the diagnosis ranks).
OPTIONAL_EFFECTS: tuple[str, ...] = tuple(n for n in CATALOGUE if n not in BASE_EFFECTS)


def get_effect(name: str) -> Effect:
    """Return the effect called ``name`` or raise ConfigError listing the known ones."""
    try:
        return CATALOGUE[name]
    except KeyError:
        known = ", ".join(CATALOGUE)
        raise ConfigError(f"unknown effect {name!r}; known effects: {known}") from None


def get_param(full_name: str) -> Param:
    """Return the parameter ``"<effect>.<param>"`` or raise ConfigError."""
    effect_name, _, param_name = full_name.partition(".")
    effect = get_effect(effect_name)
    for p in effect.params:
        if p.name == param_name:
            return p
    known = ", ".join(effect.full_names())
    raise ConfigError(f"unknown parameter {full_name!r}; {effect_name} has: {known}")


__all__ = ["BASE_EFFECTS", "CATALOGUE", "OPTIONAL_EFFECTS", "Effect", "Param", "get_effect", "get_param"]
