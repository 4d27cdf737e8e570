"""The shape every physical effect shares: a name, parameters with units and bounds, a torque.

Besides the physics, an effect carries what the diagnosis says about it: the effects that look
alike in ordinary closed-loop data, the experiment that confirms it, words for its evidence,
and, for a torque that is not linear in a parameter, the grid on which that parameter is
searched. So an effect lives in one file (see docs/workbench.md, "Your own effect").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
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
# Evidence words: (the candidate's parameters, θ at the samples used (rad), the residual torque
# there (N·m)) -> a phrase with numbers, e.g. "holding torque rises 0.02 N·m per rad".
EvidenceFn = Callable[[Mapping[str, float], FloatArray, FloatArray], str]


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

    What the diagnosis knows about it:

    ``look_alikes``
        effects that explain the same residual on ordinary closed-loop data (named with it).
    ``experiment``
        the experiment that confirms it or tells it from its look-alikes.
    ``evidence``
        words for its evidence: a template formatted with the effect's own parameters by short
        name and ``range_rad`` (the angle range the run covers), e.g.
        ``"{stiffness:.3g} N·m/rad"``, or an :data:`EvidenceFn`. The diagnosis adds how well
        the effect's torque follows the residual torque and the share of it that it explains.
    ``search``
        for a torque not linear in a parameter: the values to search it on, by parameter short
        name, e.g. ``{"centre": (-1.0, -0.5, 0.0, 0.5, 1.0)}``. Parameters linear in the torque
        need none: the regression finds them in one step.
    ``negligible``
        ``negligible(params)``: why fitted values, though detectable, are too small to be a
        missing effect (a refinement of the base model's shape), or None when they matter. The
        diagnosis then reports the effect as "significant but small", not as the verdict.
    """

    name: str
    kind: EffectKind
    description: str
    params: tuple[Param, ...]
    signature: str
    torque_nm: TorqueFn = _no_torque
    look_alikes: tuple[str, ...] = ()
    experiment: str | None = None
    evidence: str | EvidenceFn | None = None
    search: Mapping[str, Sequence[float]] = field(default_factory=dict)
    negligible: Callable[[Mapping[str, float]], str | None] | None = None

    def full_names(self) -> tuple[str, ...]:
        """Parameter names qualified by the effect name, e.g. ``("gravity.torque", ...)``."""
        return tuple(f"{self.name}.{p.name}" for p in self.params)

    def param(self, name: str) -> Param:
        """The parameter called ``name`` (short name); KeyError if it has none."""
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)
