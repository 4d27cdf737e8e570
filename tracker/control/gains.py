"""Controller gains as frozen values, one dataclass per controller structure."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from tracker.errors import ConfigError


def _check_finite(obj: object) -> None:
    for f in fields(obj):  # type: ignore[arg-type]
        v = getattr(obj, f.name)
        if not math.isfinite(v):
            raise ConfigError(f"{type(obj).__name__}.{f.name} is {v!r}, not a finite number")


@dataclass(frozen=True, slots=True)
class LeadGains:
    """The seed's first-order discrete lead C(z) = g·(z − zero)/(z − pole), on r − y (V/rad)."""

    gain_v_per_rad: float
    zero: float
    pole: float

    def __post_init__(self) -> None:
        _check_finite(self)


@dataclass(frozen=True, slots=True)
class ObserverPdGains:
    """Observer-based PID feedback plus model feedforward ("observer_pd_ff").

    ``feedforward`` and ``friction_comp`` scale the J·r'' + b·r' and Coulomb terms (0 = off,
    1 = the model's value); ``friction_band_rad_s`` smooths the friction sign;
    ``integral_limit_v`` caps the integrator's share of the command (anti-windup) and the
    disturbance compensation's; ``disturbance_comp`` (0–1) cancels that fraction of the
    observer's estimate of the torque the model does not explain; ``friction_adapt_per_s``
    is the rate (1/s of motion) at which the Coulomb feedforward learns the rig's friction
    from that estimate (0 = fixed at the model's).
    """

    kp_v_per_rad: float
    kd_v_s_per_rad: float
    ki_v_per_rad_s: float
    observer_bandwidth_hz: float
    feedforward: float = 1.0
    friction_comp: float = 1.0
    friction_band_rad_s: float = 0.02
    integral_limit_v: float = 2.0
    disturbance_comp: float = 0.0
    friction_adapt_per_s: float = 0.0

    def __post_init__(self) -> None:
        _check_finite(self)
        if self.observer_bandwidth_hz <= 0.0:
            raise ConfigError(f"observer_bandwidth_hz must be positive, got {self.observer_bandwidth_hz!r}")
        if self.friction_band_rad_s <= 0.0:
            raise ConfigError(f"friction_band_rad_s must be positive, got {self.friction_band_rad_s!r}")
        if self.friction_adapt_per_s < 0.0:
            raise ConfigError(f"friction_adapt_per_s must be ≥ 0, got {self.friction_adapt_per_s!r}")
        if self.integral_limit_v < 0.0:
            raise ConfigError(f"integral_limit_v must be ≥ 0, got {self.integral_limit_v!r}")


ControllerGains = LeadGains | ObserverPdGains
