"""Target sources: where the camera should point. Manual now; the audio talker tracker plugs in later.

A source is anything with a ``name`` and ``target_at(t_s)`` returning a :class:`Target`, a
``(pan_rad, tilt_rad)`` pair, or None when it has nothing to say (the engine then holds).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from tracker.errors import ConfigError


@dataclass(frozen=True, slots=True)
class Target:
    """Where to point (rad, load coordinates), and optionally who and what the localizer saw."""

    pan_rad: float
    tilt_rad: float
    talker: str | None = None
    azimuth_rad: float | None = None
    elevation_rad: float | None = None


@runtime_checkable
class TargetSource(Protocol):
    """Something that says where to point at time ``t_s`` (engine time, s)."""

    name: str

    def target_at(self, t_s: float) -> Target | tuple[float, float] | None:
        """The target at ``t_s``, or None to hold the last one."""
        ...


def as_target(value: Target | tuple[float, float] | None, source: str) -> Target | None:
    """Normalise what a source returned; ConfigError naming the source if it is not an angle pair."""
    if value is None or isinstance(value, Target):
        target = value
    else:
        try:
            pan, tilt = value
            target = Target(float(pan), float(tilt))
        except (TypeError, ValueError):
            raise ConfigError(
                f"target source {source!r} returned {value!r}, not (pan_rad, tilt_rad)"
            ) from None
    if target is not None and not (math.isfinite(target.pan_rad) and math.isfinite(target.tilt_rad)):
        raise ConfigError(f"target source {source!r} returned a non-finite angle {target!r}")
    return target


class ManualTarget:
    """A fixed target an operator sets (``set``)."""

    def __init__(self, pan_rad: float = 0.0, tilt_rad: float = 0.0, name: str = "manual") -> None:
        self.name = name
        self._target = Target(pan_rad, tilt_rad)

    def set(self, pan_rad: float, tilt_rad: float) -> None:
        """Point somewhere else."""
        self._target = Target(pan_rad, tilt_rad)

    def target_at(self, t_s: float) -> Target:
        return self._target


class FunctionTarget:
    """A target as a function of time (scripted tests, demos): ``fn(t_s) -> (pan, tilt) | None``."""

    def __init__(self, fn: Callable[[float], tuple[float, float] | None], name: str = "script") -> None:
        self.name = name
        self._fn = fn

    def target_at(self, t_s: float) -> Target | tuple[float, float] | None:
        return self._fn(t_s)
