"""Nominal pan/tilt presets of the catalogue (SI units, load coordinates) and parameter names."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

AxisName = Literal["pan", "tilt"]

#: Amplifier gain at the load, N·m/V: gear 6.3 · pulley 2.7 · Kt 0.0436 N·m/A · 0.1 A/V.
GAIN_NM_PER_V: float = 6.3 * 2.7 * 0.0436 * 0.1
#: Motor rotor inertia reflected through the 6.3:1 gear head, kg·m².
_MOTOR_REFLECTED: float = 6.3**2 * 1.6e-6
#: Motor-to-load ratio (gear head · pulley) used for cogging seen at the load.
MOTOR_TO_LOAD_RATIO: float = 6.3 * 2.7
#: The amplifier's own limit, V (the controllers clip here too).
AMPLIFIER_LIMIT_V: float = 10.0
#: Default share of the inertia on the motor side of a two-mass axis.
MOTOR_FRACTION: float = 0.15
#: Stiff contact used when there is backlash without compliance: frequency (Hz), damping ratio.
CONTACT_FREQUENCY_HZ: float = 150.0
CONTACT_DAMPING: float = 0.5

#: The catalogue's effects, in a fixed order.
EFFECTS: tuple[str, ...] = (
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
)


@dataclass(frozen=True, slots=True)
class Preset:
    """Nominal constants of one axis.

    Attributes
    ----------
    name : str
        ``"pan"`` or ``"tilt"``.
    inertia : float
        Total inertia at the load ``inertia.J``, kg·m².
    viscous : float
        ``viscous.b``, N·m·s/rad.
    coulomb : float
        ``coulomb.torque``, N·m.
    range_rad : float
        Half-width of the reference range used by the excitation, rad.
    """

    name: AxisName
    inertia: float
    viscous: float
    coulomb: float
    range_rad: float

    def base_params(self) -> dict[str, float]:
        """The base parameters keyed by catalogue name."""
        return {"inertia.J": self.inertia, "viscous.b": self.viscous, "coulomb.torque": self.coulomb}


PAN = Preset("pan", 0.0028 + _MOTOR_REFLECTED, 8.5e-4, 0.052, 1.2)
TILT = Preset("tilt", 0.0014 + _MOTOR_REFLECTED, 4.18e-4, 0.0605, 0.6)


def preset(axis: str) -> Preset:
    """The preset of ``axis`` (``"pan"`` or ``"tilt"``)."""
    if axis == "pan":
        return PAN
    if axis == "tilt":
        return TILT
    raise ValueError(f"unknown axis {axis!r}")


def wrap_angle(x: float) -> float:
    """``x`` wrapped to [-π, π), rad."""
    return (x + math.pi) % (2.0 * math.pi) - math.pi
