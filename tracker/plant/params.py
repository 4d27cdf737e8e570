"""Axis presets: the seed report's constants for the pan and tilt axes (Appendix A and D).

K = N·Np·Kt·Ka = 6.3 · 2.7 · 0.0436 N·m/A · 0.1 A/V = 0.07416 N·m/V at the load.
Pan: J = 0.0028 + 6.3²·1.6e-6 kg·m², b = 8.5e-4 N·m·s/rad, Coulomb 0.052 N·m; its
linearised plant is 25.9 / (s² + 0.297 s) (seed eq. 4.3).

Tilt: b = 4.18e-4, Coulomb 0.0605. The report lost the tilt load inertia (``Jltilt = ;``).
We take J_load = 0.0014 kg·m², half of pan's 0.0028: the tilt axis carries only the camera
and its bracket about an axis through their centre, while pan carries the whole tilt assembly
including the tilt motor; the report also says the pan controller "requires a larger gain due
to the larger inertia of the pan axis", so J_tilt < J_pan.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import Literal

from tracker.errors import ConfigError
from tracker.plant.effects.quantization import SEED_ENCODER_STEP_RAD

AxisName = Literal["pan", "tilt"]

MOTOR_GEAR_RATIO = 6.3
PULLEY_RATIO = 2.7
MOTOR_TORQUE_CONSTANT_NM_PER_A = 4.36e-2
AMPLIFIER_GAIN_A_PER_V = 0.1
MOTOR_INERTIA_KG_M2 = 1.6e-6
SEED_GAIN_NM_PER_V = MOTOR_GEAR_RATIO * PULLEY_RATIO * MOTOR_TORQUE_CONSTANT_NM_PER_A * AMPLIFIER_GAIN_A_PER_V

PAN_LOAD_INERTIA_KG_M2 = 0.0028
TILT_LOAD_INERTIA_KG_M2 = 0.0014  # our choice; see the module docstring


@dataclass(frozen=True, slots=True)
class AxisPreset:
    """The seed's constants for one axis: gain, base parameters, soft limits, encoder."""

    name: AxisName
    gain_nm_per_v: float
    inertia_kg_m2: float
    viscous_nm_s_per_rad: float
    coulomb_nm: float
    soft_limit_rad: float
    encoder_step_rad: float

    def base_params(self) -> MappingProxyType[str, float]:
        """The base-model parameters keyed by full name."""
        return MappingProxyType(
            {
                "inertia.J": self.inertia_kg_m2,
                "viscous.b": self.viscous_nm_s_per_rad,
                "coulomb.torque": self.coulomb_nm,
            }
        )


PAN = AxisPreset(
    name="pan",
    gain_nm_per_v=SEED_GAIN_NM_PER_V,
    inertia_kg_m2=PAN_LOAD_INERTIA_KG_M2 + MOTOR_GEAR_RATIO**2 * MOTOR_INERTIA_KG_M2,
    viscous_nm_s_per_rad=8.5e-4,
    coulomb_nm=0.052,
    soft_limit_rad=math.radians(90.0),
    encoder_step_rad=SEED_ENCODER_STEP_RAD,
)

TILT = AxisPreset(
    name="tilt",
    gain_nm_per_v=SEED_GAIN_NM_PER_V,
    inertia_kg_m2=TILT_LOAD_INERTIA_KG_M2 + MOTOR_GEAR_RATIO**2 * MOTOR_INERTIA_KG_M2,
    viscous_nm_s_per_rad=4.18e-4,
    coulomb_nm=0.0605,
    soft_limit_rad=math.radians(45.0),
    encoder_step_rad=SEED_ENCODER_STEP_RAD,
)

PRESETS: dict[str, AxisPreset] = {"pan": PAN, "tilt": TILT}


def get_preset(axis: str) -> AxisPreset:
    """Return the preset for ``axis`` ("pan" or "tilt") or raise ConfigError."""
    try:
        return PRESETS[axis]
    except KeyError:
        raise ConfigError(f"unknown axis {axis!r}; known axes: pan, tilt") from None
