"""The shape every physical effect shares: a name, parameters with units and bounds, a torque."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# How an effect acts:
#   "torque"    adds a load torque tau(theta, omega) that ``torque_nm`` evaluates
#   "input"     transforms the command before the amplifier (delay, saturation)
#   "structure" changes the mechanism's structure (two-mass: backlash, compliance)
#   "sensor"    changes only what the encoder reports (quantization)
EffectKind = Literal["base", "torque", "input", "structure", "sensor"]


@dataclass(frozen=True, slots=True)
class Param:
    """One named physical parameter of an effect, in SI units.

    ``fit=False`` marks parameters that the fitter keeps at their value unless asked
    (a datasheet constant, or a discrete one found by search, like ripple cycles).
    """

    name: str
    unit: str
    default: float
    lower: float
    upper: float
    description: str
    fit: bool = True

    def check(self, value: float, where: str) -> float:
        """Return ``value`` as float, or raise ConfigError naming the parameter and bound."""
        from tracker.errors import ConfigError

        v = float(value)
        if not np.isfinite(v):
            raise ConfigError(f"{where}: {self.name} is {value!r}, not a finite number")
        if v < self.lower or v > self.upper:
            raise ConfigError(
                f"{where}: {self.name} = {v:g} {self.unit} is outside "
                f"[{self.lower:g}, {self.upper:g}] {self.unit}"
            )
        return v


TorqueFn = Callable[[Mapping[str, float], FloatArray, FloatArray], FloatArray]


def _no_torque(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    return np.zeros_like(np.asarray(omega, dtype=float))


@dataclass(frozen=True, slots=True)
class Effect:
    """A physical effect of the axis: its parameters and the torque it adds.

    ``torque_nm(params, theta_rad, omega_rad_s)`` returns the *resisting* torque the effect
    adds to the equation of motion ``J θ'' = K u − Σ τ_effects`` (the quasi-static part; the
    simulator adds stick-slip and dynamics). ``params`` is keyed by full names
    ``"<effect>.<param>"``. Effects of kind "input", "structure" and "sensor" return zeros:
    they act through the simulator, not as a torque.
    """

    name: str
    kind: EffectKind
    description: str
    params: tuple[Param, ...]
    signature: str
    torque_nm: TorqueFn = _no_torque

    def full_names(self) -> tuple[str, ...]:
        """Parameter names qualified by the effect name, e.g. ``("gravity.torque", ...)``."""
        return tuple(f"{self.name}.{p.name}" for p in self.params)
