"""Physical constants and unit helpers (SI inside the engine; degrees only at the edges)."""

from __future__ import annotations

import math

SPEED_OF_SOUND_M_PER_S = 343.0
AMPLIFIER_LIMIT_V = 10.0
TWO_PI = 2.0 * math.pi


def deg_to_rad(angle_deg: float) -> float:
    """Degrees to radians."""
    return angle_deg * math.pi / 180.0


def rad_to_deg(angle_rad: float) -> float:
    """Radians to degrees."""
    return angle_rad * 180.0 / math.pi
