"""Draw a seeded log: the axis, the loop and at most one hidden effect, named as the workbench's
catalogue names it (README's parameter table). Sizes are drawn against the log's own floor:

    disturbance  σ_d: the std of the load torque disturbance (N·m);
    count torque τ_q = 2·J·step/h², the constant torque that moves the axis one encoder count in
                 the workbench's 30 ms prediction horizon h (a coarse encoder hides less than it).

A torque effect is at least max(5·σ_d, τ_q, 0.2·Fc); the reached sizes are written to the truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from bench.outside_gen import references as refs
from bench.outside_gen.controllers import (
    Nominal,
    OpenLoop,
    PidDerivOnMeasurement,
    StateFeedback,
    VelocityCascade,
)
from bench.outside_gen.loop import Controller, Encoder, Run, ou_disturbance, run_loop
from bench.outside_gen.plant import AxisPlant, Friction, Motor, Transmission

EFFECTS = (
    "offset",
    "coulomb_asymmetry",
    "viscous_asymmetry",
    "stiction",
    "gravity",
    "delay",
    "saturation",
    "ripple",
    "backlash",
    "compliance",
)
HORIZON_S = 0.03
RATES_HZ = (200, 250, 500, 1000, 2000)
CPR = (1000, 2048, 4096, 8192, 16384)
GEARS = (5.9, 6.3, 8.45, 9.7, 12.85)


@dataclass(frozen=True)
class Scenario:
    name: str
    seed: int
    effect: str | None
    axis: str
    rate_hz: int
    duration_s: float
    encoder: Encoder
    controller: str  # pid_dom | cascade | state_feedback | open_loop
    program: str  # s_curve | sines | steps | v_steps | v_ramps | multisine
    plant: AxisPlant
    latency_ticks: int
    delay_s: float
    disturbance_nm: float
    disturbance_corr_s: float
    dither_v: float
    u_max_v: float
    bandwidth_rad_s: float

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz

    def count_torque_nm(self) -> float:
        step = self.encoder.step_rad(self.plant.motor.gear_ratio)
        return 2 * self.plant.j_total_kgm2 * step / HORIZON_S**2


def _friction(
    rng: np.random.Generator, fc_nm: float, b_nms: float, law: str, j_kgm2: float, stribeck_excess: float
) -> Friction:
    z_pre = rng.uniform(5e-5, 3e-4)
    sigma0 = fc_nm / z_pre if law == "lugre" else 0.0
    sigma1 = 2 * rng.uniform(0.3, 1.0) * math.sqrt(sigma0 * j_kgm2) if law == "lugre" else 0.0
    return Friction(
        fc_pos_nm=fc_nm,
        fc_neg_nm=fc_nm,
        fs_nm=fc_nm * (1 + stribeck_excess),
        stribeck_rad_s=rng.uniform(0.005, 0.05),
        b_pos_nms=b_nms,
        b_neg_nms=b_nms,
        tanh_eps_rad_s=rng.uniform(1e-4, 5e-4),
        sigma0_nm_per_rad=sigma0,
        sigma1_nms_per_rad=sigma1,
        sigma1_decay_rad_s=rng.uniform(0.01, 0.1),
    )


def draw_base(name: str, seed: int, effect: str | None, duration_s: float = 20.0) -> Scenario:
    """Everything but the hidden effect (a two-mass transmission only for backlash/compliance)."""
    rng = np.random.default_rng(seed)
    axis = "tilt" if effect == "gravity" else str(rng.choice(["pan", "tilt"]))
    rate = int(rng.choice(RATES_HZ))
    gear = float(rng.choice(GEARS))
    kt = rng.uniform(0.025, 0.05)
    r_ohm = max(rng.uniform(3.0, 12.0), gear**2 * kt**2 / 0.02)  # back-EMF damping ≤ 0.02 N·m·s/rad
    two_mass = effect in ("backlash", "compliance")
    j_load = rng.uniform(0.0015, 0.004) if axis == "pan" else rng.uniform(0.0008, 0.002)
    motor_fraction = rng.uniform(0.12, 0.35) if two_mass else rng.uniform(0.01, 0.08)
    j_rotor = motor_fraction / (1 - motor_fraction) * j_load / gear**2
    motor = Motor(
        r_ohm=r_ohm,
        l_h=rng.uniform(0.1e-3, 0.6e-3) * r_ohm,
        kt_nm_per_a=kt,
        gear_ratio=gear,
        amp_gain_v_per_v=rng.uniform(1.0, 3.0),
        amp_rail_v=1e3,
        j_rotor_kgm2=j_rotor,
    )
    law = str(rng.choice(["tanh", "lugre"]))
    fc = rng.uniform(0.02, 0.06)
    share_motor = rng.uniform(0.7, 1.0) if two_mass else rng.uniform(0.5, 1.0)
    j_total = j_load + gear**2 * j_rotor
    excess = rng.uniform(0.0, 0.05)  # a Stribeck bump a careful engineer calls negligible
    f_m = _friction(rng, fc * share_motor, rng.uniform(2e-4, 1e-3), law, j_total, excess)
    f_l = _friction(rng, fc * (1 - share_motor), rng.uniform(0, 4e-4), law, j_total, excess)
    plant = AxisPlant(motor=motor, j_load_kgm2=j_load, law=law, friction_motor=f_m, friction_load=f_l)
    controller = str(
        rng.choice(["pid_dom", "cascade", "state_feedback", "open_loop"], p=[0.3, 0.25, 0.25, 0.2])
    )
    program = str(
        rng.choice(
            ["v_steps", "v_ramps", "multisine"]
            if controller == "open_loop"
            else ["s_curve", "sines", "steps"]
        )
    )
    nyq_rad_s = 2 * math.pi * rate
    bw = rng.uniform(60, 200) if controller == "cascade" else rng.uniform(12, 35)
    bw = min(bw, nyq_rad_s / (10 if controller == "cascade" else 40))
    cpr = int(rng.choice(CPR))
    encoder = Encoder(
        cpr, on_motor=two_mass or bool(rng.random() < 0.6), rounding=str(rng.choice(["floor", "round"]))
    )
    return Scenario(
        name=name,
        seed=seed,
        effect=effect,
        axis=axis,
        rate_hz=rate,
        duration_s=duration_s,
        encoder=encoder,
        controller=controller,
        program=program,
        plant=plant,
        latency_ticks=int(controller != "open_loop" and rng.random() < 0.3 and effect != "delay"),
        delay_s=0.0,
        disturbance_nm=rng.uniform(0.5e-3, 3e-3),
        disturbance_corr_s=rng.uniform(0.02, 0.2),
        dither_v=rng.uniform(0.05, 0.2) if controller != "open_loop" and rng.random() < 0.5 else 0.0,
        u_max_v=rng.uniform(6.0, 12.0),
        bandwidth_rad_s=bw,
    )


def prbs(n: int, rng: np.random.Generator) -> np.ndarray:
    """±1 held for 1–5 ticks at random; shape (n,)."""
    out: list[float] = []
    while len(out) < n:
        out.extend([float(rng.choice([-1.0, 1.0]))] * int(rng.integers(1, 6)))
    return np.asarray(out[:n])


def controller_for(sc: Scenario, seed: int) -> Controller:
    """The loop's controller with its reference (or voltage program), seeded apart from the plant."""
    rng = np.random.default_rng(seed + 7919)
    n = int(sc.duration_s * sc.rate_hz)
    t = np.arange(n) * sc.period_s
    pl, m = sc.plant, sc.plant.motor
    fc = pl.friction_motor.fc_pos_nm + pl.friction_load.fc_pos_nm
    b = pl.friction_motor.b_pos_nms + pl.friction_load.b_pos_nms + m.back_emf_damping_nms_per_rad
    if sc.controller == "open_loop":
        level = min(rng.uniform(2.0, 4.0) * fc / m.gain_nm_per_v, 0.8 * sc.u_max_v)
        make = {"v_steps": refs.voltage_steps, "v_ramps": refs.voltage_ramps, "multisine": refs.multisine}
        return OpenLoop(make[sc.program](t, rng, level))
    nom = Nominal(
        j_kgm2=pl.j_total_kgm2 * rng.uniform(0.7, 1.3),
        b_nms=b * rng.uniform(0.5, 2.0),
        gain_nm_per_v=m.gain_nm_per_v * rng.uniform(0.9, 1.1),
        coulomb_nm=fc * rng.uniform(0.7, 1.2),
    )
    span = 1.4 if sc.axis == "pan" else 0.6
    if sc.program == "s_curve":
        ref, vel = refs.s_curve_moves(t, rng, span, rng.uniform(0.5, 2.0))
    elif sc.program == "sines":
        ref, vel = refs.sinusoids(t, rng, span)
    else:
        ref, vel = refs.random_steps(t, rng, span * 0.6)
    dither = prbs(n, rng) * sc.dither_v
    if sc.controller == "pid_dom":
        return PidDerivOnMeasurement(
            nom,
            sc.bandwidth_rad_s,
            sc.period_s,
            sc.u_max_v,
            ref,
            vel,
            dither,
            coulomb_ff=bool(rng.random() < 0.5),
        )
    if sc.controller == "cascade":
        return VelocityCascade(nom, sc.bandwidth_rad_s, sc.period_s, sc.u_max_v, ref, vel, dither)
    return StateFeedback(nom, sc.bandwidth_rad_s, sc.period_s, sc.u_max_v, ref, vel, dither)


def simulate(sc: Scenario) -> Run:
    n = int(sc.duration_s * sc.rate_hz)
    dist = ou_disturbance(
        n + 1, sc.period_s, sc.disturbance_nm, sc.disturbance_corr_s, np.random.default_rng(sc.seed + 104729)
    )
    return run_loop(
        sc.plant,
        controller_for(sc, sc.seed),
        sc.period_s,
        n,
        sc.encoder,
        latency_ticks=sc.latency_ticks,
        delay_s=sc.delay_s,
        disturbance_nm=dist,
    )


def torque_floor_nm(sc: Scenario) -> float:
    fc = sc.plant.friction_motor.fc_pos_nm + sc.plant.friction_load.fc_pos_nm
    return max(5 * sc.disturbance_nm, sc.count_torque_nm(), 0.2 * fc)


def with_effect(sc: Scenario, rng: np.random.Generator) -> Scenario:
    """Hide sc.effect in the plant (or the drive) at a clearly present size."""
    pl, eff = sc.plant, sc.effect
    floor = torque_floor_nm(sc)
    fm, fl = pl.friction_motor, pl.friction_load
    if eff == "offset":
        return replace(
            sc, plant=replace(pl, bias_nm=float(rng.choice([-1, 1])) * floor * rng.uniform(1.0, 1.6))
        )
    if eff == "coulomb_asymmetry":
        d = floor * rng.uniform(1.0, 1.5) * float(rng.choice([-1, 1]))
        share = fm.fc_pos_nm / (fm.fc_pos_nm + fl.fc_pos_nm)
        d = max(d, -0.6 * (fm.fc_pos_nm + fl.fc_pos_nm))
        return replace(
            sc,
            plant=replace(
                pl,
                friction_motor=replace(fm, fc_neg_nm=fm.fc_neg_nm + d * share),
                friction_load=replace(fl, fc_neg_nm=fl.fc_neg_nm + d * (1 - share)),
            ),
        )
    if eff == "viscous_asymmetry":
        b_total = fm.b_pos_nms + fl.b_pos_nms + pl.motor.back_emf_damping_nms_per_rad
        extra = max(b_total * rng.uniform(0.8, 1.5), floor / 0.5)  # ≥ the floor at 0.5 rad/s
        return replace(sc, plant=replace(pl, friction_motor=replace(fm, b_neg_nms=fm.b_neg_nms + extra)))
    if eff == "stiction":
        k = 1 + max(rng.uniform(0.5, 1.0), floor / (fm.fc_pos_nm + fl.fc_pos_nm))
        vs = rng.uniform(0.01, 0.05)
        return replace(
            sc,
            plant=replace(
                pl,
                friction_motor=replace(fm, fs_nm=fm.fc_pos_nm * k, stribeck_rad_s=vs),
                friction_load=replace(fl, fs_nm=fl.fc_pos_nm * k, stribeck_rad_s=vs),
            ),
        )
    if eff == "gravity":
        amp = max(floor * rng.uniform(1.0, 1.5), rng.uniform(0.02, 0.05))
        return replace(sc, plant=replace(pl, gravity_nm=amp, gravity_phase_rad=rng.uniform(-0.5, 0.5)))
    if eff == "delay":
        return replace(sc, delay_s=max(rng.uniform(3, 8) * sc.period_s, rng.uniform(4e-3, 12e-3)))
    if eff == "ripple":
        step = sc.encoder.step_rad(pl.motor.gear_ratio)
        ok = [c for c in (3, 4, 6, 8) if 2 * math.pi / (c * pl.motor.gear_ratio) >= 25 * step]
        cyc = float(rng.choice(ok or [1.5]))
        return replace(
            sc,
            plant=replace(
                pl,
                cog_nm=floor * rng.uniform(1.0, 1.5),
                cog_cycles_per_motor_rev=cyc,
                cog_phase_rad=rng.uniform(0, 2 * math.pi),
            ),
        )
    if eff == "backlash":
        step = sc.encoder.step_rad(pl.motor.gear_ratio)
        gap = max(rng.uniform(0.006, 0.015), 6 * step)
        return replace(sc, plant=replace(pl, transmission=Transmission("backlash", gap_rad=gap)))
    if eff == "compliance":
        hz = min(rng.uniform(8, 30), sc.rate_hz / 8)
        return replace(
            sc,
            plant=replace(
                pl, transmission=Transmission("belt", belt_hz=hz, belt_damping=rng.uniform(0.05, 0.2))
            ),
        )
    raise ValueError(f"unknown effect {eff!r}")


def with_saturation(sc: Scenario, clean_run: Run, rng: np.random.Generator) -> Scenario:
    """An amplifier rail that clips the commands the clean run's top 6–12 % of |u| reach."""
    fc = sc.plant.friction_motor.fc_pos_nm + sc.plant.friction_load.fc_pos_nm
    level_v = float(np.quantile(np.abs(clean_run.u_v), 1 - rng.uniform(0.06, 0.12)))
    level_v = max(level_v, 1.5 * fc / sc.plant.motor.gain_nm_per_v)
    m = sc.plant.motor
    return replace(sc, plant=replace(sc.plant, motor=replace(m, amp_rail_v=level_v * m.amp_gain_v_per_v)))
