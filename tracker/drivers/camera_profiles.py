"""PTZ camera profiles: position units, ranges and speed tables per make (camera_profiles.toml).

A profile maps the console's angles (rad; pan positive to the left seen from behind the
camera, tilt positive up) to the camera's VISCA counts and speed codes, and gives the
emulator's twin its dynamics. Figures and their sources are in the TOML file.
"""

from __future__ import annotations

import bisect
import math
import tomllib
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from tracker.drivers.motor import AXES
from tracker.drivers.visca_protocol import PAN_SPEED_MAX, TILT_SPEED_MAX
from tracker.errors import ConfigError

PROFILES_FILE = Path(__file__).with_name("camera_profiles.toml")
DEFAULT_PROFILE = "generic"
_KEYS = {
    "deg_per_count", "pan_range_deg", "tilt_range_deg", "pan_speeds_deg_s", "tilt_speeds_deg_s",
    "accel_deg_s2", "backlash_deg", "zoom_max", "zoom_counts_s", "pan_sign", "tilt_sign",
}


@dataclass(frozen=True, slots=True)
class CameraProfile:
    """One make's figures in SI units. ``speeds_rad_s[axis][k]`` is the speed of code k + 1."""

    name: str
    rad_per_count: float
    range_rad: dict[str, tuple[float, float]]  # per axis, in the console's frame
    speeds_rad_s: dict[str, tuple[float, ...]]
    sign: dict[str, int]  # console angle = sign * VISCA angle
    accel_rad_s2: float
    backlash_rad: float
    zoom_max: int
    zoom_counts_s: float

    def to_counts(self, axis: str, angle_rad: float) -> int:
        """The VISCA position (counts) of a console angle (rad)."""
        return int(round(self.sign[axis] * angle_rad / self.rad_per_count))

    def to_rad(self, axis: str, counts: int) -> float:
        """The console angle (rad) of a VISCA position (counts)."""
        return self.sign[axis] * counts * self.rad_per_count

    def max_speed_rad_s(self, axis: str) -> float:
        """The fastest speed code's speed (rad/s)."""
        return self.speeds_rad_s[axis][-1]

    def speed_code(self, axis: str, speed_rad_s: float) -> int:
        """The largest code whose speed does not exceed ``speed_rad_s`` (at least 1)."""
        table = self.speeds_rad_s[axis]
        return max(1, bisect.bisect_right(table, abs(speed_rad_s) * (1 + 1e-9)))

    def code_speed_rad_s(self, axis: str, code: int) -> float:
        """The speed (rad/s) of speed ``code`` (clamped to the table)."""
        table = self.speeds_rad_s[axis]
        return table[min(max(code, 1), len(table)) - 1]


def _floats(name: str, key: str, value: Any, n: int | None = None) -> tuple[float, ...]:
    if not isinstance(value, list) or not all(isinstance(v, int | float) for v in value):
        raise ConfigError(f"camera profile {name!r}: {key} must be a list of numbers, got {value!r}")
    out = tuple(float(v) for v in value)
    if n is not None and len(out) != n:
        raise ConfigError(f"camera profile {name!r}: {key} needs {n} values, got {len(out)}")
    if not all(math.isfinite(v) for v in out):
        raise ConfigError(f"camera profile {name!r}: {key} has a non-finite value")
    return out


def _positive(name: str, key: str, value: Any) -> float:
    if not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
        raise ConfigError(f"camera profile {name!r}: {key} must be a number > 0, got {value!r}")
    return float(value)


def profile_from_mapping(name: str, spec: dict[str, Any]) -> CameraProfile:
    """Validate one profile table (degrees) into a :class:`CameraProfile` (radians)."""
    missing = sorted(_KEYS - set(spec))
    unknown = sorted(set(spec) - _KEYS)
    if missing or unknown:
        raise ConfigError(
            f"camera profile {name!r}: missing {missing or 'nothing'}, unknown {unknown or 'nothing'}")
    deg = math.radians(1.0)
    sign = {}
    for axis in AXES:
        s = spec[f"{axis}_sign"]
        if s not in (-1, 1):
            raise ConfigError(f"camera profile {name!r}: {axis}_sign must be 1 or -1, got {s!r}")
        sign[axis] = int(s)
    ranges = {}
    speeds = {}
    for axis, top in (("pan", PAN_SPEED_MAX), ("tilt", TILT_SPEED_MAX)):
        lo, hi = _floats(name, f"{axis}_range_deg", spec[f"{axis}_range_deg"], 2)
        if not lo < 0.0 < hi:
            raise ConfigError(f"camera profile {name!r}: {axis}_range_deg [{lo}, {hi}] must contain 0")
        a, b = sorted((sign[axis] * lo * deg, sign[axis] * hi * deg))
        ranges[axis] = (a, b)
        table = _floats(name, f"{axis}_speeds_deg_s", spec[f"{axis}_speeds_deg_s"], top)
        if any(v <= 0 for v in table) or any(b2 <= a2 for a2, b2 in zip(table, table[1:], strict=False)):
            raise ConfigError(f"camera profile {name!r}: {axis}_speeds_deg_s must rise and be > 0")
        speeds[axis] = tuple(v * deg for v in table)
    zoom_max = spec["zoom_max"]
    if not isinstance(zoom_max, int) or not 0 < zoom_max <= 0x7FFF:
        raise ConfigError(f"camera profile {name!r}: zoom_max must be an integer in 1..32767")
    backlash = spec["backlash_deg"]
    if not isinstance(backlash, int | float) or not 0 <= backlash < 5:
        raise ConfigError(f"camera profile {name!r}: backlash_deg must be in [0, 5), got {backlash!r}")
    return CameraProfile(
        name=name,
        rad_per_count=_positive(name, "deg_per_count", spec["deg_per_count"]) * deg,
        range_rad=ranges,
        speeds_rad_s=speeds,
        sign=sign,
        accel_rad_s2=_positive(name, "accel_deg_s2", spec["accel_deg_s2"]) * deg,
        backlash_rad=float(backlash) * deg,
        zoom_max=zoom_max,
        zoom_counts_s=_positive(name, "zoom_counts_s", spec["zoom_counts_s"]),
    )


@cache
def _shipped() -> dict[str, CameraProfile]:
    data = tomllib.loads(PROFILES_FILE.read_text(encoding="utf-8"))
    return {name: profile_from_mapping(name, spec) for name, spec in data.items()}


def profile_names() -> tuple[str, ...]:
    """Names of the shipped profiles."""
    return tuple(sorted(_shipped()))


def get_profile(name: str = DEFAULT_PROFILE) -> CameraProfile:
    """A shipped profile by name; ConfigError listing the names otherwise."""
    profiles = _shipped()
    try:
        return profiles[name]
    except KeyError:
        raise ConfigError(
            f"unknown camera profile {name!r}; profiles are {', '.join(sorted(profiles))}") from None
