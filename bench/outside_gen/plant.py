"""The axis as numbers: motor, gear, inertias, friction per side, transmission, torques.

`AxisPlant.pack()` gives the vector `physics.advance` integrates; `AxisPlant.workbench_truth()`
gives the same axis in the names and units of the workbench's catalogue (README, docs/workbench.md)
as a rigid-body equivalent: K = N·Kt·G_amp/R at DC, viscous = mechanical + back-EMF N²·Kt·Ke/R.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from bench.outside_gen import physics as ph


@dataclass(frozen=True)
class Motor:
    r_ohm: float
    l_h: float
    kt_nm_per_a: float
    gear_ratio: float
    amp_gain_v_per_v: float
    amp_rail_v: float
    j_rotor_kgm2: float

    @property
    def ke_v_s_per_rad(self) -> float:
        return self.kt_nm_per_a  # SI: back-EMF constant equals torque constant

    @property
    def gain_nm_per_v(self) -> float:
        return self.gear_ratio * self.kt_nm_per_a * self.amp_gain_v_per_v / self.r_ohm

    @property
    def back_emf_damping_nms_per_rad(self) -> float:
        return self.gear_ratio**2 * self.kt_nm_per_a * self.ke_v_s_per_rad / self.r_ohm

    @property
    def electrical_time_constant_s(self) -> float:
        return self.l_h / self.r_ohm


@dataclass(frozen=True)
class Friction:
    """One side's friction (load coordinates). Static level fs ≥ the Coulomb levels."""

    fc_pos_nm: float
    fc_neg_nm: float
    fs_nm: float
    stribeck_rad_s: float
    b_pos_nms: float
    b_neg_nms: float
    tanh_eps_rad_s: float = 2e-4
    sigma0_nm_per_rad: float = 0.0
    sigma1_nms_per_rad: float = 0.0
    sigma1_decay_rad_s: float = 0.05

    def packed(self) -> list[float]:
        return [
            self.fc_pos_nm,
            self.fc_neg_nm,
            max(self.fs_nm, self.fc_pos_nm, self.fc_neg_nm),
            self.stribeck_rad_s,
            self.b_pos_nms,
            self.b_neg_nms,
            self.tanh_eps_rad_s,
            self.sigma0_nm_per_rad,
            self.sigma1_nms_per_rad,
            self.sigma1_decay_rad_s,
        ]


@dataclass(frozen=True)
class Transmission:
    kind: str = "rigid"  # rigid | belt | backlash
    belt_hz: float = 0.0
    belt_damping: float = 0.0
    gap_rad: float = 0.0
    contact_hz: float = 250.0  # gear mesh stiffness when in contact (backlash)


@dataclass(frozen=True)
class AxisPlant:
    motor: Motor
    j_load_kgm2: float
    law: str  # tanh | lugre
    friction_motor: Friction
    friction_load: Friction
    transmission: Transmission = field(default_factory=Transmission)
    gravity_nm: float = 0.0
    gravity_phase_rad: float = 0.0
    bias_nm: float = 0.0
    cog_nm: float = 0.0  # ripple amplitude at the load
    cog_cycles_per_motor_rev: float = 0.0
    cog_phase_rad: float = 0.0

    @property
    def j_motor_kgm2(self) -> float:
        return self.motor.gear_ratio**2 * self.motor.j_rotor_kgm2

    @property
    def j_total_kgm2(self) -> float:
        return self.j_motor_kgm2 + self.j_load_kgm2

    @property
    def ripple_cycles_per_rev(self) -> float:
        return self.cog_cycles_per_motor_rev * self.motor.gear_ratio

    def pack(self) -> np.ndarray:
        m, tr = self.motor, self.transmission
        p = np.zeros(ph.N_PARAMS)
        p[ph.P_R_OHM], p[ph.P_L_H], p[ph.P_KT] = m.r_ohm, m.l_h, m.kt_nm_per_a
        p[ph.P_KE], p[ph.P_N], p[ph.P_GAMP], p[ph.P_VRAIL] = (
            m.ke_v_s_per_rad,
            m.gear_ratio,
            m.amp_gain_v_per_v,
            m.amp_rail_v,
        )
        p[ph.P_JM], p[ph.P_JL] = self.j_motor_kgm2, self.j_load_kgm2
        p[ph.P_MODE] = {"rigid": ph.MODE_RIGID, "belt": ph.MODE_BELT, "backlash": ph.MODE_BACKLASH}[tr.kind]
        jr = self.j_motor_kgm2 * self.j_load_kgm2 / self.j_total_kgm2
        if tr.kind == "belt":
            w = 2 * math.pi * tr.belt_hz
            p[ph.P_K_NM_RAD], p[ph.P_C_NMS_RAD] = w * w * jr, 2 * tr.belt_damping * w * jr
        elif tr.kind == "backlash":
            w = 2 * math.pi * tr.contact_hz
            p[ph.P_K_NM_RAD], p[ph.P_C_NMS_RAD], p[ph.P_GAP_RAD] = w * w * jr, 2 * 0.3 * w * jr, tr.gap_rad
        p[ph.P_GRAV_NM], p[ph.P_GRAV_PHASE], p[ph.P_BIAS_NM] = (
            self.gravity_nm,
            self.gravity_phase_rad,
            self.bias_nm,
        )
        p[ph.P_COG_NM], p[ph.P_COG_CYC], p[ph.P_COG_PHASE] = (
            self.cog_nm,
            self.ripple_cycles_per_rev,
            self.cog_phase_rad,
        )
        p[ph.P_LAW] = ph.LAW_LUGRE if self.law == "lugre" else ph.LAW_TANH
        p[ph.P_FRIC_M : ph.P_FRIC_M + 10] = self.friction_motor.packed()
        p[ph.P_FRIC_L : ph.P_FRIC_L + 10] = self.friction_load.packed()
        return p

    def workbench_truth(self) -> dict[str, float]:
        """The rigid-body equivalent in the catalogue's parameter names (SI units)."""
        fm, fl, m = self.friction_motor, self.friction_load, self.motor
        b_emf = m.back_emf_damping_nms_per_rad
        truth = {
            "gain_nm_per_v": m.gain_nm_per_v,
            "inertia.J": self.j_total_kgm2,
            "viscous.b": fm.b_pos_nms + fl.b_pos_nms + b_emf,
            "coulomb.torque": fm.fc_pos_nm + fl.fc_pos_nm,
            "coulomb_asymmetry.negative": fm.fc_neg_nm + fl.fc_neg_nm,
            "viscous_asymmetry.negative": fm.b_neg_nms + fl.b_neg_nms + b_emf,
            "offset.torque": self.bias_nm,
            "stiction.static_torque": max(fm.fs_nm, fm.fc_pos_nm) + max(fl.fs_nm, fl.fc_pos_nm),
            "stiction.velocity": fm.stribeck_rad_s,
            "gravity.torque": self.gravity_nm,
            "gravity.phase": self.gravity_phase_rad,
            "saturation.limit": m.amp_rail_v / m.amp_gain_v_per_v,
            "ripple.amplitude": self.cog_nm,
            "ripple.cycles_per_rev": self.ripple_cycles_per_rev,
            "ripple.phase": self.cog_phase_rad,
            "backlash.width": self.transmission.gap_rad,
            "compliance.frequency": self.transmission.belt_hz,
            "compliance.damping": self.transmission.belt_damping,
            "inertia.motor_fraction": self.j_motor_kgm2 / self.j_total_kgm2,
        }
        return truth

    def as_dict(self) -> dict[str, object]:
        return asdict(self)
