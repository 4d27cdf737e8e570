"""A true axis by catalogue names: packing for the integrator, sub-step size and consistent start."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tests.truthgen import plant as pl
from tests.truthgen.friction import LAW_KINETIC, LAW_LUGRE
from tests.truthgen.loop import new_state
from tests.truthgen.presets import AMPLIFIER_LIMIT_V, CONTACT_DAMPING, CONTACT_FREQUENCY_HZ

FloatArray = NDArray[np.float64]

FRICTION_LAWS: tuple[str, ...] = ("karnopp", "stribeck", "lugre")


@dataclass(slots=True)
class TrueAxis:
    """The ground truth of one axis.

    Attributes
    ----------
    gain : float
        Amplifier gain K at the load, N·m/V.
    params : dict
        Every true parameter by catalogue name (``inertia.J``, ``viscous.b``,
        ``coulomb.torque``, ``inertia.motor_fraction``, ``quantization.step`` and those of the
        hidden effects), SI units.
    hidden : list of str
        The hidden catalogue effects (two-mass when ``backlash`` or ``compliance`` is among them).
    friction_law : str
        ``"karnopp"``, ``"stribeck"`` or ``"lugre"``.
    friction : dict
        Parameters of the friction law beyond the catalogue (Stribeck shape of a clean log,
        LuGre σ0 N·m/rad, σ1 N·m·s/rad).
    """

    gain: float
    params: dict[str, float]
    hidden: list[str]
    friction_law: str = "karnopp"
    friction: dict[str, float] = field(default_factory=dict)

    @property
    def two_mass(self) -> bool:
        """Whether the axis has a motor side and a load side."""
        return "backlash" in self.hidden or "compliance" in self.hidden

    def belt(self) -> tuple[float, float, float]:
        """Belt stiffness (N·m/rad), damping (N·m·s/rad) and frequency (Hz); zeros when rigid."""
        if not self.two_mass:
            return 0.0, 0.0, 0.0
        p = self.params
        j = p["inertia.J"]
        f = p["inertia.motor_fraction"]
        j_eff = f * (1.0 - f) * j
        if "compliance" in self.hidden:
            freq, zeta = p["compliance.frequency"], p["compliance.damping"]
        else:
            freq, zeta = CONTACT_FREQUENCY_HZ, CONTACT_DAMPING
        k = (2.0 * math.pi * freq) ** 2 * j_eff
        return k, 2.0 * zeta * math.sqrt(k * j_eff), freq

    def pack(self) -> FloatArray:
        """The packed parameter vector of :mod:`tests.truthgen.plant`."""
        p = self.params
        P = np.zeros(pl.N_PARAMS)
        j = p["inertia.J"]
        frac = p["inertia.motor_fraction"]
        P[pl.K] = self.gain
        if self.two_mass:
            P[pl.JM], P[pl.JL], P[pl.TWO] = frac * j, (1.0 - frac) * j, 1.0
        else:
            P[pl.JM], P[pl.JL] = j, (1.0 - frac) * j
        P[pl.BP] = p["viscous.b"]
        P[pl.BN] = p.get("viscous_asymmetry.negative", p["viscous.b"])
        P[pl.FCP] = p["coulomb.torque"]
        P[pl.FCN] = p.get("coulomb_asymmetry.negative", p["coulomb.torque"])
        P[pl.VS], P[pl.DELTA] = 1.0, 2.0
        if "stiction.static_torque" in p:
            P[pl.FEX] = p["stiction.static_torque"] - p["coulomb.torque"]
            P[pl.VS] = p["stiction.velocity"]
        elif self.friction_law in ("stribeck", "lugre") and "static_torque" in self.friction:
            P[pl.FEX] = self.friction["static_torque"] - p["coulomb.torque"]
            P[pl.VS] = self.friction["velocity"]
            P[pl.DELTA] = self.friction.get("exponent", 2.0)
        P[pl.OFFSET] = p.get("offset.torque", 0.0)
        P[pl.TG] = p.get("gravity.torque", 0.0)
        P[pl.GPH] = p.get("gravity.phase", 0.0)
        P[pl.ULIM] = p.get("saturation.limit", AMPLIFIER_LIMIT_V)
        P[pl.RA] = p.get("ripple.amplitude", 0.0)
        P[pl.RN] = p.get("ripple.cycles_per_rev", 0.0)
        P[pl.RPH] = p.get("ripple.phase", 0.0)
        P[pl.BW] = p.get("backlash.width", 0.0)
        P[pl.CK], P[pl.CC], _ = self.belt()
        if self.friction_law == "lugre":
            if self.two_mass:
                raise ValueError("LuGre friction is implemented for the rigid axis only")
            P[pl.LAW] = LAW_LUGRE
            P[pl.S0] = self.friction["sigma0"]
            P[pl.S1] = self.friction["sigma1"]
        else:
            P[pl.LAW] = LAW_KINETIC
        return P

    def max_substep(self, period: float, refine: float = 1.0) -> float:
        """Largest integration sub-step (s): ≤ period/50, ≤ belt period/100, LuGre bristle scale."""
        h = period / 50.0
        _, _, freq = self.belt()
        if freq > 0.0:
            h = min(h, 1.0 / (100.0 * freq))
        if self.friction_law == "lugre":
            # bristle rate σ0·|ω|/Fc at 10 rad/s times h stays ≤ 0.25
            rate = self.friction["sigma0"] * 10.0 / self.params["coulomb.torque"]
            h = min(h, 0.25 / rate)
            omega_b = math.sqrt(self.friction["sigma0"] / self.params["inertia.J"])
            h = min(h, 0.05 / omega_b)
        return h / refine

    def initial_state(self, dist0: float = 0.0) -> FloatArray:
        """At rest, motor angle 0; a two-mass load hangs on the belt in static equilibrium."""
        x = new_state()
        if not self.two_mass:
            return x
        k, _, _ = self.belt()
        half = 0.5 * self.params.get("backlash.width", 0.0)
        tg = self.params.get("gravity.torque", 0.0)
        ph = self.params.get("gravity.phase", 0.0)
        thl = 0.0
        for _ in range(50):  # load equilibrium: k·dz = Tg·sin(θl + φ) − dist0
            need = tg * math.sin(thl + ph) - dist0
            dz = need / k
            thl = -(dz + math.copysign(half, dz)) if dz != 0.0 else 0.0
        x[pl.TH_L] = thl
        x[pl.REG] = pl.region_of(x[pl.TH_M] - thl, self.pack())
        return x
