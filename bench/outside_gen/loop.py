"""The tick loop, in the order of an ordinary controller (README's CSV convention):

at tick i read the encoder (θ_i, the angle at t_i), compute u_i, log (t_i, u_i, θ_i); the drive
applies u_i over [t_i, t_{i+1}) — later when the loop has a computational latency (whole ticks)
or the drive a transport delay (any time) — and the plant is integrated to t_{i+1}.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bench.outside_gen import physics as ph
from bench.outside_gen.plant import AxisPlant


class Controller(Protocol):
    def command_v(self, i: int, theta_rad: float) -> float: ...


@dataclass(frozen=True)
class Encoder:
    counts_per_rev: int
    on_motor: bool  # counts per motor revolution (step /N at the load) or per load revolution
    rounding: str  # "floor" | "round"

    def step_rad(self, gear_ratio: float) -> float:
        return 2 * math.pi / (self.counts_per_rev * (gear_ratio if self.on_motor else 1.0))

    def read_rad(self, angle_rad: float, gear_ratio: float) -> float:
        step = self.step_rad(gear_ratio)
        q = math.floor(angle_rad / step) if self.rounding == "floor" else round(angle_rad / step)
        return q * step


@dataclass(frozen=True)
class Run:
    t_s: np.ndarray
    u_v: np.ndarray
    theta_rad: np.ndarray  # encoder readings, load coordinates
    motor_true_rad: np.ndarray  # motor-side angle at t_i (load coordinates), unquantized
    load_true_rad: np.ndarray
    current_a: np.ndarray
    disturbance_nm: np.ndarray


def ou_disturbance(
    n: int, period_s: float, sigma_nm: float, corr_s: float, rng: np.random.Generator
) -> np.ndarray:
    """Ornstein–Uhlenbeck torque sampled at the ticks, stationary std sigma_nm."""
    a = math.exp(-period_s / corr_s)
    d = np.zeros(n)
    d[0] = rng.normal(0, sigma_nm)
    e = rng.normal(0, sigma_nm * math.sqrt(1 - a * a), n)
    for i in range(1, n):
        d[i] = a * d[i - 1] + e[i]
    return d


def run_loop(
    plant: AxisPlant,
    controller: Controller,
    period_s: float,
    n_ticks: int,
    encoder: Encoder,
    latency_ticks: int = 0,
    delay_s: float = 0.0,
    disturbance_nm: np.ndarray | None = None,
) -> Run:
    """Run n_ticks of the loop; the command applied over [t_i, t_i+1) lags by latency + delay."""
    p = plant.pack()
    n_sub = ph.substeps_for(period_s)
    dist = np.zeros(n_ticks + 1) if disturbance_nm is None else disturbance_nm
    lag_ticks = latency_ticks + delay_s / period_s
    whole = math.floor(lag_ticks + 1e-12)
    frac = lag_ticks - whole
    gear = plant.motor.gear_ratio
    x = np.zeros(ph.N_STATE)
    u = np.zeros(n_ticks)
    theta = np.zeros(n_ticks)
    motor, load, cur = np.zeros(n_ticks), np.zeros(n_ticks), np.zeros(n_ticks)
    for i in range(n_ticks):
        motor[i], load[i], cur[i] = x[1], (x[1] if plant.transmission.kind == "rigid" else x[3]), x[0]
        theta[i] = encoder.read_rad(x[1], gear)
        u[i] = controller.command_v(i, theta[i])
        before = u[i - whole - 1] if i - whole - 1 >= 0 else 0.0
        after = u[i - whole] if i - whole >= 0 else 0.0
        x = ph.advance(x, p, before, after, frac, dist[i], dist[i + 1], period_s, n_sub)
        if not np.all(np.isfinite(x)):
            raise FloatingPointError(f"plant diverged at tick {i}")
    t = np.arange(n_ticks) * period_s
    return Run(t, u, theta, motor, load, cur, dist[:n_ticks])


def write_csv(path: str, run: Run) -> None:
    """The README's format: header t,u,theta; one row per tick."""
    data = np.column_stack([run.t_s, run.u_v, run.theta_rad])
    np.savetxt(path, data, delimiter=",", header="t,u,theta", comments="", fmt=["%.6f", "%.6f", "%.9f"])
