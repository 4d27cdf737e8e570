"""An independent PTZ log generator: ground truth for the camera workbench's tests.

Imports nothing from ``tracker``: its own speed table, latency (split between the command's way
out and the position reply's age), acceleration limit, backlash and position counts, simulated
by plain time stepping (0.25 ms Euler), so a shared mistake with the workbench's exact
integration cannot hide. Commands come at 20–50 Hz from a mix of a proportional tracker
following random targets through the reported angle (closed loop) and random held steps, and
are logged the camera workbench's way: row i = (t_i, the step sent at t_i, the angle reported at t_i).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field


@dataclass
class PtzTruth:
    """The hidden camera. Speeds in deg/s per step (index 0 = step 1), angles in degrees."""

    period_s: float = 0.04
    table_pos_deg_s: list[float] = field(default_factory=list)
    table_neg_deg_s: list[float] = field(default_factory=list)
    cmd_latency_s: float = 0.0
    report_latency_s: float = 0.0
    accel_deg_s2: float | None = None  # None: reaches any speed at once
    backlash_deg: float = 0.0
    count_deg: float = 0.069444

    @property
    def latency_s(self) -> float:
        return self.cmd_latency_s + self.report_latency_s


def linear_table(n: int, per_step_deg_s: float) -> list[float]:
    return [per_step_deg_s * k for k in range(1, n + 1)]


def geometric_table(
    n: int, slowest: float, fastest: float, rng: random.Random, wiggle: float = 0.03
) -> list[float]:
    """A rising table, geometric like the makes' tables, each step jittered by ``wiggle``."""
    r = (fastest / slowest) ** (1.0 / (n - 1))
    out = [slowest * r**i * (1.0 + rng.uniform(-wiggle, wiggle)) for i in range(n)]
    for i in range(1, n):
        out[i] = max(out[i], out[i - 1] * 1.01)
    return out


def _step_for(table: list[float], speed: float) -> int:
    """The largest step whose speed does not exceed ``speed`` (0 below half the slowest)."""
    if speed < 0.5 * table[0]:
        return 0
    k = 1
    for i, v in enumerate(table):
        if v <= speed:
            k = i + 1
    return k


def generate(truth: PtzTruth, duration_s: float, seed: int) -> tuple[list[float], list[int], list[float]]:
    """(t s, signed step, reported angle rad) per command period."""
    rng = random.Random(seed)
    h = 0.00025
    per_row = max(1, round(truth.period_s / h))
    n_rows = int(duration_s / truth.period_s)
    lag_cmd = round(truth.cmd_latency_s / h)
    lag_rep = round(truth.report_latency_s / h)
    n_fine = n_rows * per_row + 1
    applied = [0.0] * (n_fine + lag_cmd + 1)  # target speed (deg/s) in force at each fine step
    load = [0.0] * (n_fine + 1)
    motor = speed = ld = 0.0
    half = 0.5 * truth.backlash_deg
    t_out: list[float] = []
    steps: list[int] = []
    theta: list[float] = []
    target = 0.0
    next_target_t = 0.0
    hold_step, hold_until = 0, -1.0
    fine = 0
    for i in range(n_rows):
        t = i * truth.period_s
        # the reply the camera gave, as old as the report latency, in whole counts
        seen = load[max(0, fine - lag_rep)]
        reported = truth.count_deg * round(seen / truth.count_deg)
        if t >= next_target_t:
            target = rng.uniform(-80.0, 80.0)
            next_target_t = t + rng.uniform(1.0, 4.0)
            if rng.random() < 0.35:  # an open-loop stretch at a random step
                hold_until = t + rng.uniform(0.3, 1.5)
                n = len(truth.table_pos_deg_s)
                hold_step = rng.randint(1, n) * (1 if reported < 0 else -1)
                if abs(reported) < 40 and rng.random() < 0.5:
                    hold_step = -hold_step
        if t < hold_until and abs(reported) < 140:
            step = hold_step
        else:
            v = 1.5 * (target - reported)
            table = truth.table_pos_deg_s if v > 0 else truth.table_neg_deg_s
            step = _step_for(table, abs(v)) * (1 if v > 0 else -1)
        t_out.append(t)
        steps.append(step)
        theta.append(math.radians(reported))
        v_cmd = (
            0.0
            if step == 0
            else (truth.table_pos_deg_s[step - 1] if step > 0 else -truth.table_neg_deg_s[-step - 1])
        )
        for f in range(fine, fine + per_row):
            applied[f + lag_cmd] = v_cmd
        for f in range(fine, fine + per_row):
            want = applied[f]
            if truth.accel_deg_s2 is None:
                speed = want
            else:
                dv = truth.accel_deg_s2 * h
                speed += max(-dv, min(dv, want - speed))
            motor += speed * h
            ld = min(max(ld, motor - half), motor + half)
            load[f + 1] = ld
        fine += per_row
    return t_out, steps, theta


def to_csv(t: list[float], steps: list[int], theta: list[float]) -> str:
    rows = ["t,speed_cmd,theta"] + [f"{a:.6f},{s},{th:.9f}" for a, s, th in zip(t, steps, theta, strict=True)]
    return "\n".join(rows) + "\n"


def random_truth(
    rng: random.Random,
    *,
    latency: bool = False,
    table: bool = False,
    accel: bool = False,
    backlash: bool = False,
    n_steps: int = 18,
) -> PtzTruth:
    """A camera with the chosen effects hidden (the others absent: linear map, no latency, ...)."""
    period = 1.0 / rng.uniform(20.0, 50.0)
    if table:
        pos = geometric_table(n_steps, rng.uniform(0.8, 2.0), rng.uniform(60.0, 120.0), rng)
        neg = [v * rng.uniform(0.9, 1.1) for v in pos]
        for i in range(1, n_steps):
            neg[i] = max(neg[i], neg[i - 1] * 1.01)
    else:
        pos = neg = linear_table(n_steps, rng.uniform(2.0, 5.0))
    lat = rng.uniform(0.06, 0.2) if latency else 0.0
    split = rng.uniform(0.3, 0.7)
    return PtzTruth(
        period_s=period,
        table_pos_deg_s=pos,
        table_neg_deg_s=list(neg),
        cmd_latency_s=lat * split,
        report_latency_s=lat * (1 - split),
        accel_deg_s2=rng.uniform(80.0, 300.0) if accel else None,
        backlash_deg=rng.uniform(0.3, 1.0) if backlash else 0.0,
    )
