"""The camera-operator policy: the settings a room's operators tune, with units, bounds and meanings.

Both talker trackers (:class:`~tracker.audio.tracking.TrackerSettings`,
:class:`~tracker.audio.map_tracking.MapTrackerSettings`) carry these fields among their many
others; :class:`CameraPolicy` is the part people tune per room (through the service's API, its
config file or the console), and :meth:`CameraPolicy.apply` writes it into either tracker's
settings. :data:`POLICY_FIELDS` is the catalogue the validation messages and the console read:
each field's unit, allowed range and meaning in one line.

A running tracker takes a new policy between two frames (its ``settings`` replaced; see
:meth:`tracker.audio.stream.StreamingLocator.set_policy`): no restart, no state lost.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal, TypeVar

from tracker.errors import ConfigError, OutOfRange

Unit = Literal["s", "rad", "count"]


@dataclass(frozen=True, slots=True)
class PolicyField:
    """One tunable setting: its name (unit in the name), unit, allowed range and meaning."""

    name: str
    unit: Unit
    low: float
    high: float
    meaning: str


POLICY_FIELDS: tuple[PolicyField, ...] = (
    PolicyField("reaction_time_s", "s", 0.05, 3.0,
                "a new voice must last this long before the camera cuts to it "
                "(a cough, a door or a burst of echoes does not move it)"),
    PolicyField("min_hold_s", "s", 0.0, 30.0,
                "after a cut the camera stays on the new talker at least this long, "
                "unless the room fell silent"),
    PolicyField("pause_tolerance_s", "s", 0.2, 10.0,
                "a silence shorter than this keeps the talker's turn; after a longer one "
                "the next voice is taken as soon as it is confirmed"),
    PolicyField("deadband_rad", "rad", 0.0, math.radians(30.0),
                "the shot stays put while the talker moves less than this "
                "(a seated person shifting does not move the camera)"),
    PolicyField("wide_after_switches", "count", 2, 50,
                "this many cuts back and forth between the same two people "
                "give a wide shot that holds both"),
    PolicyField("wide_window_s", "s", 1.0, 300.0,
                "those cuts count towards the wide shot when they all fall within this time"),
    PolicyField("wide_release_s", "s", 0.0, 120.0,
                "the wide shot ends once one talker has held the floor this long"),
    PolicyField("lead_s", "s", 0.0, 2.0,
                "a walking talker is framed where she will be this far ahead "
                "(makes up for the camera's lag)"),
)
FIELDS_BY_NAME: dict[str, PolicyField] = {f.name: f for f in POLICY_FIELDS}

_Settings = TypeVar("_Settings")


@dataclass(frozen=True, slots=True)
class CameraPolicy:
    """How the camera operator behaves (see :data:`POLICY_FIELDS` for meanings and bounds).

    Defaults are the meeting room's, the same as both trackers' own defaults.
    """

    reaction_time_s: float = 0.2
    min_hold_s: float = 2.0
    pause_tolerance_s: float = 1.5
    deadband_rad: float = math.radians(3.0)
    wide_after_switches: int = 4
    wide_window_s: float = 20.0
    wide_release_s: float = 6.0
    lead_s: float = 0.3

    def __post_init__(self) -> None:
        for f in POLICY_FIELDS:
            check_value(f, getattr(self, f.name))

    def apply(self, settings: _Settings) -> _Settings:
        """``settings`` (a tracker's frozen settings) with this policy's fields replaced."""
        return dataclasses.replace(settings, **self.values())  # type: ignore[type-var]

    def values(self) -> dict[str, float]:
        """Field name -> value (SI units, as in the names)."""
        return {f.name: getattr(self, f.name) for f in POLICY_FIELDS}

    @classmethod
    def of(cls, settings: Any) -> CameraPolicy:  # noqa: ANN401 - either tracker's settings
        """The policy part of a tracker's settings."""
        return cls(**{f.name: getattr(settings, f.name) for f in POLICY_FIELDS})

    def replaced(self, changes: Mapping[str, object], where: str = "camera policy") -> CameraPolicy:
        """This policy with ``changes`` (name -> value, SI units); ConfigError naming an unknown
        field, OutOfRange naming a bad value, its allowed range and its meaning."""
        unknown = sorted(set(changes) - set(FIELDS_BY_NAME))
        if unknown:
            raise ConfigError(f"{where}: unknown setting(s) {', '.join(unknown)}; "
                              f"settings: {', '.join(FIELDS_BY_NAME)}")
        checked = {name: check_value(FIELDS_BY_NAME[name], value, where)
                   for name, value in changes.items()}
        return dataclasses.replace(self, **checked)  # type: ignore[arg-type]


def check_value(f: PolicyField, value: object, where: str = "camera policy") -> float:
    """``value`` if it is a number within ``f``'s range (a whole number for a count), else
    OutOfRange naming the field, the value, the range and the meaning."""
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    try:
        number = float(value) if ok else math.nan  # type: ignore[arg-type]
    except OverflowError:  # an integer past float's range
        ok, number = False, math.nan
    if f.unit == "count":
        ok = ok and math.isfinite(number) and number == int(number)
    if not ok or not math.isfinite(number) or not f.low <= number <= f.high:
        raise OutOfRange(f"{where}: {f.name}={value!r} is outside {describe_range(f)} "
                         f"({f.meaning})", f.name, value, f.low, f.high, f.unit)
    return int(number) if f.unit == "count" else number


def describe_range(f: PolicyField) -> str:
    """The allowed range in words: "0-30 s", "0-30°", "whole numbers 2-50"."""
    if f.unit == "rad":
        return f"{math.degrees(f.low):g}-{math.degrees(f.high):g}° ({f.low:.4g}-{f.high:.4g} rad)"
    if f.unit == "count":
        return f"whole numbers {f.low:g}-{f.high:g}"
    return f"{f.low:g}-{f.high:g} {f.unit}"
