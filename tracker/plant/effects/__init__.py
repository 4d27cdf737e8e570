"""The catalogue of physical effects of an axis, read by the simulator, the fitter and the diagnosis.

Every module of this package that defines ``EFFECT`` is an effect of the catalogue (found by
:mod:`pkgutil`); an effect defined elsewhere joins with :func:`register_effect`, and the modules
named in the environment variable ``TRACKER_EFFECTS`` (``package.module`` or a ``.py`` path,
comma-separated) are loaded when the catalogue is first imported. Adding an effect is adding
one file: see docs/workbench.md, "Your own effect".

The effects in :data:`BUILTIN_EFFECTS` have code of their own in the simulator, the screening
and the fit starts. Every other effect is *generic*: a torque that depends on the angle only,
τ(θ), which the simulator reads from a table and the diagnosis fits through the derivatives of
its torque with respect to its parameters (:func:`check_generic` says what it must satisfy).
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import os
import pkgutil
import re
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import overload

import numpy as np

from tracker.errors import ConfigError
from tracker.plant.effects.base import Effect, EvidenceFn, FloatArray, Param

BASE_EFFECTS: tuple[str, ...] = ("inertia", "viscous", "coulomb")

# Effects with code of their own in the engine, in the order the catalogue has always listed
# them (the diagnosis and the console show them so). Other modules of the package follow,
# alphabetically, then registered effects in the order they were registered.
BUILTIN_EFFECTS: tuple[str, ...] = (
    "inertia",
    "viscous",
    "coulomb",
    "coulomb_asymmetry",
    "viscous_asymmetry",
    "offset",
    "stiction",
    "gravity",
    "delay",
    "saturation",
    "ripple",
    "backlash",
    "compliance",
    "quantization",
)

ENV_VAR = "TRACKER_EFFECTS"
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
_PARAM_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
# Speeds (rad/s) at which a generic effect's torque must equal its torque at rest.
_PROBE_SPEEDS = (-10.0, -0.1, 0.1, 10.0)
_PROBE_POINTS = 17

CATALOGUE: dict[str, Effect] = {}


class EffectNames(Sequence[str]):
    """A live, read-only view of effect names: recomputed from the catalogue at every use, so it
    includes effects registered after it was created."""

    def __init__(self, names: Callable[[], tuple[str, ...]]) -> None:
        self._names = names

    @overload
    def __getitem__(self, i: int) -> str: ...
    @overload
    def __getitem__(self, i: slice) -> Sequence[str]: ...
    def __getitem__(self, i: int | slice) -> str | Sequence[str]:
        return self._names()[i]

    def __len__(self) -> int:
        return len(self._names())

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __contains__(self, name: object) -> bool:
        return name in self._names()

    def __repr__(self) -> str:
        return f"EffectNames({self._names()!r})"


def optional_effects() -> tuple[str, ...]:
    """Effects a model can be missing (what the diagnosis ranks), in catalogue order."""
    return tuple(n for n in CATALOGUE if n not in BASE_EFFECTS)


def generic_effects() -> tuple[str, ...]:
    """Effects without code of their own in the engine (position-dependent torques)."""
    return tuple(n for n in CATALOGUE if n not in BUILTIN_EFFECTS)


def is_generic(name: str) -> bool:
    """True for an effect of the catalogue that is not built in (see :func:`check_generic`)."""
    return name in CATALOGUE and name not in BUILTIN_EFFECTS


# Effects a model can be missing: a live view of optional_effects().
OPTIONAL_EFFECTS: Sequence[str] = EffectNames(optional_effects)


def get_effect(name: str) -> Effect:
    """Return the effect called ``name`` or raise ConfigError listing the known ones."""
    try:
        return CATALOGUE[name]
    except KeyError:
        known = ", ".join(CATALOGUE)
        raise ConfigError(
            f"unknown effect {name!r}; known effects: {known} (a site's own effect loads through "
            f"{ENV_VAR}: docs/workbench.md, 'Your own effect')"
        ) from None


def get_param(full_name: str) -> Param:
    """Return the parameter ``"<effect>.<param>"`` or raise ConfigError."""
    effect_name, _, param_name = full_name.partition(".")
    effect = get_effect(effect_name)
    for p in effect.params:
        if p.name == param_name:
            return p
    known = ", ".join(effect.full_names())
    raise ConfigError(f"unknown parameter {full_name!r}; {effect_name} has: {known}")


def _check_shape(effect: Effect, where: str) -> None:
    """Name, kind and parameters of any effect, built in or not."""
    if not isinstance(effect, Effect):
        raise ConfigError(f"{where}: expected an Effect, got {type(effect).__name__}")
    if not _NAME.match(effect.name):
        raise ConfigError(
            f"{where}: effect name {effect.name!r} must be lower case letters, digits and '_', "
            "starting with a letter"
        )
    seen: set[str] = set()
    for p in effect.params:
        if not _PARAM_NAME.match(p.name):
            raise ConfigError(f"{where}: parameter name {p.name!r} of {effect.name} is not an identifier")
        if p.name in seen:
            raise ConfigError(f"{where}: {effect.name} has two parameters called {p.name!r}")
        seen.add(p.name)
        if math.isnan(p.lower) or math.isnan(p.upper) or not p.lower < p.upper:
            raise ConfigError(
                f"{where}: {effect.name}.{p.name} has bounds [{p.lower:g}, {p.upper:g}]: lower must be "
                "below upper"
            )
        p.check(p.default, f"{where}: default of {effect.name}")
    if isinstance(effect.evidence, str):
        try:
            effect.evidence.format(**{p.name: p.default for p in effect.params}, range_rad=1.0)
        except (KeyError, IndexError, ValueError) as exc:
            raise ConfigError(
                f"{where}: evidence template of {effect.name} cannot be filled from its parameters "
                f"and range_rad: {exc!r}"
            ) from None
    for name, grid in effect.search.items():
        if name not in seen:
            raise ConfigError(f"{where}: {effect.name} searches {name!r}, which is not one of its parameters")
        values = np.asarray(grid, dtype=float)
        prm = effect.param(name)
        if values.ndim != 1 or values.size < 2 or not np.all(np.isfinite(values)):
            raise ConfigError(f"{where}: search grid of {effect.name}.{name} needs two or more finite values")
        if values.min() < prm.lower or values.max() > prm.upper:
            raise ConfigError(
                f"{where}: search grid of {effect.name}.{name} leaves its bounds "
                f"[{prm.lower:g}, {prm.upper:g}] {prm.unit}"
            )


def _probe_values(effect: Effect) -> list[dict[str, float]]:
    """Parameter sets to probe a torque with: the defaults, then each parameter moved toward its
    bounds (a velocity term that a default of zero switches off must still show)."""
    base = {f"{effect.name}.{p.name}": p.default for p in effect.params}
    out = [base]
    for p in effect.params:
        reach = 1.0 + abs(p.default)
        for bound in (p.lower, p.upper):
            step = max(-reach, min(reach, 0.5 * (bound - p.default)))
            if step:
                out.append({**base, f"{effect.name}.{p.name}": p.default + step})
    return out


def _torque_at(
    effect: Effect, params: Mapping[str, float], theta: FloatArray, w: float, where: str
) -> FloatArray:
    try:
        tau = np.asarray(effect.torque_nm(params, theta, np.full_like(theta, w)), dtype=float)
    except Exception as exc:  # a user's function: report whatever it raised, and where
        raise ConfigError(f"{where}: the torque of {effect.name} fails: {exc!r}") from exc
    if tau.shape != theta.shape:
        raise ConfigError(
            f"{where}: the torque of {effect.name} must return θ's shape {theta.shape}, got {tau.shape}"
        )
    return tau


def check_position_only(effect: Effect, params: Mapping[str, float], where: str) -> None:
    """Raise ConfigError unless ``effect``'s torque with ``params`` is finite and independent of
    the velocity (the generic simulator path tabulates τ(θ) at rest)."""
    theta = np.linspace(-math.pi, math.pi, _PROBE_POINTS)
    rest = _torque_at(effect, params, theta, 0.0, where)
    if not np.all(np.isfinite(rest)):
        raise ConfigError(f"{where}: the torque of {effect.name} is not finite at {dict(params)}")
    tol = 1e-9 * max(1.0, float(np.max(np.abs(rest))))
    for w in _PROBE_SPEEDS:
        moving = _torque_at(effect, params, theta, w, where)
        if not np.max(np.abs(moving - rest)) <= tol:
            raise ConfigError(
                f"{where}: the torque of {effect.name} depends on the velocity (at ω = {w:g} rad/s it "
                "differs from the torque at rest); only built-in effects may: a new effect is a "
                "torque of the angle alone (see docs/workbench.md, 'Your own effect')"
            )


def check_generic(effect: Effect, where: str) -> None:
    """What an effect without code of its own must satisfy, or ConfigError.

    It is a torque (kind ``"torque"``) with a torque function of the angle only: the
    simulator tabulates it at rest, the screening differentiates it with respect to its
    parameters.
    """
    if effect.kind != "torque":
        raise ConfigError(
            f"{where}: effect {effect.name!r} is of kind {effect.kind!r}; only built-in effects may act "
            "through the command, the structure or the sensor — a new effect must be a 'torque'"
        )
    if not effect.params:
        raise ConfigError(f"{where}: effect {effect.name!r} has no parameters to fit")
    for values in _probe_values(effect):
        check_position_only(effect, values, where)


def register_effect(effect: Effect, where: str = "register_effect") -> Effect:
    """Add ``effect`` to the catalogue (the simulator, fit, diagnosis, CLI and console then know it).

    Registering the same object again does nothing. Raises ConfigError for a name that is taken,
    bad parameters or bounds, or a torque the engine cannot simulate (see :func:`check_generic`).
    Returns ``effect``.
    """
    _check_shape(effect, where)
    known = CATALOGUE.get(effect.name)
    if known is effect:
        return effect
    if effect.name in BUILTIN_EFFECTS:
        raise ConfigError(f"{where}: {effect.name!r} is the name of a built-in effect")
    if known is not None:
        raise ConfigError(f"{where}: an effect called {effect.name!r} is already in the catalogue")
    check_generic(effect, where)
    CATALOGUE[effect.name] = effect
    return effect


def unregister_effect(name: str) -> None:
    """Remove a registered effect (tests; a site's plug-in reloaded). Built-ins stay."""
    if name in BUILTIN_EFFECTS:
        raise ConfigError(f"cannot unregister the built-in effect {name!r}")
    CATALOGUE.pop(name, None)


def _import(spec: str) -> ModuleType:
    if spec.endswith(".py"):
        path = Path(spec).expanduser().resolve()
        name = f"tracker_effect_{path.stem}"
        loaded = sys.modules.get(name)
        if loaded is not None and getattr(loaded, "__file__", None) == str(path):
            return loaded  # loaded before (the environment, then the service's setting)
        loader_spec = importlib.util.spec_from_file_location(name, path)
        if loader_spec is None or loader_spec.loader is None or not path.is_file():
            raise FileNotFoundError(f"no such file: {path}")
        module = importlib.util.module_from_spec(loader_spec)
        sys.modules[name] = module
        try:
            loader_spec.loader.exec_module(module)
        except BaseException:
            sys.modules.pop(name, None)
            raise
        return module
    return importlib.import_module(spec)


def _module_effects(module: ModuleType) -> list[Effect]:
    found = getattr(module, "EFFECTS", ())
    one = getattr(module, "EFFECT", None)
    return [*([one] if one is not None else []), *found]


def load_effect_modules(specs: str | Iterable[str], where: str = ENV_VAR) -> tuple[str, ...]:
    """Import effect plug-in modules and register the ``EFFECT`` (or ``EFFECTS``) each defines.

    ``specs``: module names (``site.effects.cable``) or paths of ``.py`` files, as an iterable
    or one comma-separated string. Returns the names of the effects loaded. Raises ConfigError
    naming the module when one cannot be imported or defines no valid effect.
    """
    items = specs.split(",") if isinstance(specs, str) else list(specs)
    names: list[str] = []
    for raw in items:
        spec = raw.strip()
        if not spec:
            continue
        before = set(CATALOGUE)
        try:
            module = _import(spec)
        except ConfigError as exc:
            raise ConfigError(f"{where}: effect module {spec!r}: {exc}") from exc
        except Exception as exc:
            raise ConfigError(f"{where}: cannot load effect module {spec!r}: {exc!r}") from exc
        effects = _module_effects(module)
        for effect in effects:
            register_effect(effect, f"{where}: {spec}")
        added = [e.name for e in effects] + [n for n in CATALOGUE if n not in before]
        if not added:
            raise ConfigError(f"{where}: module {spec!r} defines no EFFECT and registers no effect")
        names.extend(n for n in added if n not in names)
    return tuple(names)


def _discover() -> None:
    """Fill the catalogue with this package's effect modules: built-ins first, in their order."""
    found: dict[str, Effect] = {}
    for info in pkgutil.iter_modules(__path__):
        if info.name == "base" or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        effect = getattr(module, "EFFECT", None)
        if effect is None:
            continue
        where = f"{__name__}.{info.name}"
        _check_shape(effect, where)
        if effect.name in found:
            raise ConfigError(f"{where}: a second effect called {effect.name!r}")
        found[effect.name] = effect
    missing = [n for n in BUILTIN_EFFECTS if n not in found]
    assert not missing, f"built-in effect modules missing: {missing}"
    for name in BUILTIN_EFFECTS:
        CATALOGUE[name] = found[name]
    for name in sorted(set(found) - set(BUILTIN_EFFECTS)):
        check_generic(found[name], f"{__name__}.{name}")
        CATALOGUE[name] = found[name]


_discover()
load_effect_modules(os.environ.get(ENV_VAR, ""))


__all__ = [
    "BASE_EFFECTS",
    "BUILTIN_EFFECTS",
    "CATALOGUE",
    "ENV_VAR",
    "OPTIONAL_EFFECTS",
    "Effect",
    "EffectNames",
    "EvidenceFn",
    "FloatArray",
    "Param",
    "check_generic",
    "check_position_only",
    "generic_effects",
    "get_effect",
    "get_param",
    "is_generic",
    "load_effect_modules",
    "optional_effects",
    "register_effect",
    "unregister_effect",
]
