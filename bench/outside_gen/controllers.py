"""Controllers, each a small object stepped once per tick: `command_v(i, theta_meas_rad)`.

They see only the encoder reading and the reference (arrays over ticks), like a real loop.
Gains are designed on a deliberately imperfect nominal model J s² + b s with gain K.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Nominal:
    """The designer's guess of the axis (not the truth)."""

    j_kgm2: float
    b_nms: float
    gain_nm_per_v: float
    coulomb_nm: float


class PidDerivOnMeasurement:
    """PI-D: P and I on the error, D on the filtered measurement, conditional-integration anti-windup,
    optional Coulomb feed-forward on the reference's velocity sign and a PRBS dither."""

    def __init__(
        self,
        nom: Nominal,
        bandwidth_rad_s: float,
        period_s: float,
        u_max_v: float,
        ref_rad: np.ndarray,
        ref_vel: np.ndarray,
        dither_v: np.ndarray,
        coulomb_ff: bool,
    ) -> None:
        w = bandwidth_rad_s
        self.kp = 3 * w * w * nom.j_kgm2 / nom.gain_nm_per_v
        self.ki = w**3 * nom.j_kgm2 / nom.gain_nm_per_v
        self.kd = max(3 * w * nom.j_kgm2 - nom.b_nms, 0.2 * w * nom.j_kgm2) / nom.gain_nm_per_v
        self.tf_s = 1.0 / (8 * w)
        self.t_s, self.u_max = period_s, u_max_v
        self.ref, self.ref_vel, self.dither = ref_rad, ref_vel, dither_v
        self.ff_v = nom.coulomb_nm / nom.gain_nm_per_v if coulomb_ff else 0.0
        self.integ, self.d_term, self.prev = 0.0, 0.0, math.nan

    def command_v(self, i: int, theta_rad: float) -> float:
        if math.isnan(self.prev):
            self.prev = theta_rad
        e = self.ref[i] - theta_rad
        a = self.tf_s / (self.tf_s + self.t_s)
        self.d_term = a * self.d_term - self.kd * (theta_rad - self.prev) / (self.tf_s + self.t_s)
        self.prev = theta_rad
        ff = self.ff_v * float(np.tanh(self.ref_vel[i] / 0.02))
        raw = self.kp * e + self.integ + self.d_term + ff + self.dither[i]
        u = min(max(raw, -self.u_max), self.u_max)
        if u == raw or np.sign(e) != np.sign(raw):
            self.integ += self.ki * e * self.t_s
        return u


class VelocityCascade:
    """Outer P position loop → speed reference (plus the reference's speed); inner PI speed loop on
    a speed estimated from the encoder by a backward difference and a first-order low-pass."""

    def __init__(
        self,
        nom: Nominal,
        inner_rad_s: float,
        period_s: float,
        u_max_v: float,
        ref_rad: np.ndarray,
        ref_vel: np.ndarray,
        dither_v: np.ndarray,
    ) -> None:
        self.kpv = inner_rad_s * nom.j_kgm2 / nom.gain_nm_per_v
        self.kiv = self.kpv * inner_rad_s / 5
        self.kpp = inner_rad_s / 5
        self.tf_s = 1.0 / (3 * inner_rad_s)
        self.t_s, self.u_max = period_s, u_max_v
        self.ref, self.ref_vel, self.dither = ref_rad, ref_vel, dither_v
        self.speed, self.integ, self.prev = 0.0, 0.0, math.nan

    def command_v(self, i: int, theta_rad: float) -> float:
        if math.isnan(self.prev):
            self.prev = theta_rad
        raw_speed = (theta_rad - self.prev) / self.t_s
        self.prev = theta_rad
        a = self.t_s / (self.tf_s + self.t_s)
        self.speed += a * (raw_speed - self.speed)
        w_ref = self.kpp * (self.ref[i] - theta_rad) + self.ref_vel[i]
        e = w_ref - self.speed
        raw = self.kpv * e + self.integ + self.dither[i]
        u = min(max(raw, -self.u_max), self.u_max)
        if u == raw:
            self.integ += self.kiv * e * self.t_s
        return u


class StateFeedback:
    """u = k1 (r − θ̂) + k2 (ṙ − ω̂) + ki ∫(r − θ) with an alpha-beta observer for θ̂, ω̂
    (pole placement on the nominal model: a triple pole at −w)."""

    def __init__(
        self,
        nom: Nominal,
        bandwidth_rad_s: float,
        period_s: float,
        u_max_v: float,
        ref_rad: np.ndarray,
        ref_vel: np.ndarray,
        dither_v: np.ndarray,
    ) -> None:
        w = bandwidth_rad_s
        self.k1 = 3 * w * w * nom.j_kgm2 / nom.gain_nm_per_v
        self.k2 = max(3 * w * nom.j_kgm2 - nom.b_nms, 0.2 * w * nom.j_kgm2) / nom.gain_nm_per_v
        self.ki = w**3 * nom.j_kgm2 / nom.gain_nm_per_v
        obs_w = min(6 * w, 0.5 / period_s)
        self.alpha = 1 - math.exp(-2 * obs_w * period_s)
        self.beta = self.alpha**2 / (2 - self.alpha)
        self.t_s, self.u_max = period_s, u_max_v
        self.ref, self.ref_vel, self.dither = ref_rad, ref_vel, dither_v
        self.th, self.om, self.integ, self.started = 0.0, 0.0, 0.0, False

    def command_v(self, i: int, theta_rad: float) -> float:
        if not self.started:
            self.th, self.started = theta_rad, True
        pred = self.th + self.om * self.t_s
        resid = theta_rad - pred
        self.th = pred + self.alpha * resid
        self.om += self.beta * resid / self.t_s
        e = self.ref[i] - theta_rad
        raw = self.k1 * (self.ref[i] - self.th) + self.k2 * (self.ref_vel[i] - self.om) + self.integ
        raw += self.dither[i]
        u = min(max(raw, -self.u_max), self.u_max)
        if u == raw:
            self.integ += self.ki * e * self.t_s
        return u


class OpenLoop:
    """A precomputed voltage program (steps, ramps, multisine)."""

    def __init__(self, u_v: np.ndarray) -> None:
        self.u_v = u_v

    def command_v(self, i: int, theta_rad: float) -> float:
        return float(self.u_v[i])
