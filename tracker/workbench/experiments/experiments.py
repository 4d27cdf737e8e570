"""Closed-loop measurement generation on the twin: a realistic run with hidden effects, as a log.

A PD position controller with friction feed-forward follows a reference made of steps with
holds, slow ramps (low speed, starts from rest) and a sine sweep, with dither on the command,
a random disturbance torque on the load and a quantizing encoder — what a person would record
on the rig to identify it. The "true" model may carry any effects of the catalogue (the hidden
effects); the controller only knows the base model.

The loop is our own small compiled loop on top of :func:`tracker.plant.simulate.advance`
(the controls engineer's closed-loop simulator serves the tracking controllers; this one needs
dither, disturbances and an exactly logged command, so it stays here).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from tracker.errors import ConfigError
from tracker.plant.effects.quantization import SEED_ENCODER_STEP_RAD
from tracker.plant.model import AxisModel
from tracker.plant.simulate import I_Q, advance, encoder_rad, initial_state, pack_params
from tracker.units import AMPLIFIER_LIMIT_V
from tracker.workbench.measurements.data import Measurement

FloatArray = NDArray[np.float64]
SHAPE_GAIN = 30.0  # 1/s


@dataclass(frozen=True, slots=True)
class Excitation:
    """How hard the generated run excites the axis.

    ``range_rad`` bounds the reference (± around zero); ``dither_v`` is the standard deviation of
    white noise added to the command; ``disturbance_nm`` the standard deviation of a random load
    torque with correlation time ``disturbance_tau_s``; ``bandwidth_rad_s`` the PD loop's
    natural frequency (damping 0.7).
    """

    range_rad: float = 1.2
    dither_v: float = 0.08
    disturbance_nm: float = 0.002
    disturbance_tau_s: float = 0.05
    bandwidth_rad_s: float = 25.0


def reference_trajectory(
    duration_s: float, dt_s: float, rng: np.random.Generator, range_rad: float
) -> FloatArray:
    """A reference of steps with holds, slow ramps and a sine sweep. Returns shape (n,), rad.

    The segments cycle so that every 10 s contains all three kinds: steps (0.6–1.2 s holds),
    triangle ramps at 0.05–0.6 rad/s and a chirp from 0.2 to 2.5 Hz.
    """
    n = int(round(duration_s / dt_s))
    ref = np.zeros(n)
    k = 0
    pos = 0.0
    kind = 0
    while k < n:
        if kind == 0:  # steps with holds
            seg_end = min(n, k + int(4.0 / dt_s))
            while k < seg_end:
                hold = int(rng.uniform(0.6, 1.2) / dt_s)
                pos = float(rng.uniform(-range_rad, range_rad))
                ref[k : k + hold] = pos
                k += hold
        elif kind == 1:  # slow ramps, each to a new random point
            seg_end = min(n, k + int(3.0 / dt_s))
            while k < seg_end:
                target = float(rng.uniform(-range_rad, range_rad))
                speed = float(rng.uniform(0.05, 0.6))
                m = max(1, int(abs(target - pos) / speed / dt_s))
                ref[k : k + m] = pos + (target - pos) * np.arange(1, m + 1)[: max(0, min(m, n - k))] / m
                k += m
                pos = target
        else:  # sine sweep around the current position
            m = min(n - k, int(3.0 / dt_s))
            t = np.arange(m) * dt_s
            f0, f1, span = 0.2, 2.5, 3.0
            phase = 2 * math.pi * (f0 * t + 0.5 * (f1 - f0) / span * t**2)
            amp = 0.5 * range_rad * np.minimum(1.0, 0.6 / (f0 + (f1 - f0) * t / span))
            centre = float(np.clip(pos, -0.4 * range_rad, 0.4 * range_rad))
            ref[k : k + m] = centre + amp * np.sin(phase)
            k += m
            pos = float(ref[k - 1])
        kind = (kind + 1) % 3
    return ref


def shape_reference(
    ref: FloatArray, dt_s: float, max_speed: float, max_accel: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Rate- and acceleration-limit ``ref``; returns (position, velocity, acceleration), shape (n,)."""
    return _shape(np.ascontiguousarray(ref, dtype=float), dt_s, max_speed, max_accel)


@njit(cache=True)
def _shape(ref: FloatArray, dt: float, vmax: float, amax: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    n = ref.shape[0]
    p = np.empty(n)
    v = np.empty(n)
    a = np.empty(n)
    x, xd = ref[0], 0.0
    for k in range(n):
        err = ref[k] - x
        # Velocity that stops at the target under max deceleration, linear (time constant
        # 1/SHAPE_GAIN) near it so the discrete shaper settles without chattering.
        mag = min(vmax, math.sqrt(2.0 * amax * abs(err)), SHAPE_GAIN * abs(err))
        vt = mag if err >= 0 else -mag
        acc = (vt - xd) / dt
        acc = min(amax, max(-amax, acc))
        xd += acc * dt
        x += xd * dt
        p[k], v[k], a[k] = x, xd, acc
    return p, v, a


@njit(cache=True)
def _closed_loop(
    P: FloatArray,
    dt: float,
    ref_p: FloatArray,
    ref_v: FloatArray,
    ref_a: FloatArray,
    gains: FloatArray,
    dither: FloatArray,
    dist: FloatArray,
    x0: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """PD + feed-forward loop; gains = [kp, kd, J/K, b/K, Fc/K, velocity filter pole]."""
    n = ref_p.shape[0]
    u = np.zeros(n)
    theta = np.empty(n)
    load = np.empty(n)
    x = x0.copy()
    kp, kd, jk, bk, fk, pole = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5]
    prev = encoder_rad(x, P)
    vel = 0.0
    for k in range(n):
        y = encoder_rad(x, P)
        theta[k] = y
        load[k] = x[2]
        vel = pole * vel + (1.0 - pole) * (y - prev) / dt
        prev = y
        sgn = 0.0
        if ref_v[k] > 1e-3:
            sgn = 1.0
        elif ref_v[k] < -1e-3:
            sgn = -1.0
        cmd = kp * (ref_p[k] - y) + kd * (ref_v[k] - vel) + jk * ref_a[k] + bk * ref_v[k] + fk * sgn
        cmd += dither[k]
        if cmd > 10.0:
            cmd = 10.0
        elif cmd < -10.0:
            cmd = -10.0
        u[k] = cmd
        advance(x, P, u, k, dt, dist[k])
    return u, theta, load


def generate_measurement(
    true_model: AxisModel,
    duration_s: float = 30.0,
    seed: int = 0,
    dt_s: float = 1e-3,
    excitation: Excitation | None = None,
    encoder_step_rad: float = SEED_ENCODER_STEP_RAD,
) -> Measurement:
    """Record a closed-loop run of the twin ``true_model`` (hidden effects and all).

    Parameters
    ----------
    true_model : the rig's real physics (its effects are what the diagnosis must find).
    duration_s, dt_s : length and sample interval of the log (s).
    seed : seeds the reference, dither and disturbance (same seed, same log).
    excitation : reference range, dither, disturbance and loop bandwidth.
    encoder_step_rad : encoder resolution at the load; 0 gives an ideal sensor (a model with
        its own ``quantization`` effect keeps its step).

    Returns
    -------
    Measurement with ``u_v`` the command the controller sent (±10 V) and ``theta_rad`` the
    encoder angle, shape (n,) each.
    """
    if not (duration_s > 0 and dt_s > 0 and duration_s / dt_s >= 200):
        raise ConfigError(f"duration {duration_s!r} s at {dt_s!r} s gives fewer than 200 samples")
    ex = excitation or Excitation()
    rng = np.random.default_rng(seed)
    P = pack_params(true_model, dt_s, quantize=True)
    if encoder_step_rad > 0 and not true_model.has("quantization"):
        # Set the step in the packed vector: AxisModel.with_effect would re-create the model
        # and reset an asymmetry's "negative" value to the positive one.
        P[I_Q] = encoder_step_rad
    n = int(round(duration_s / dt_s))
    j, k_gain = true_model.params["inertia.J"], true_model.gain_nm_per_v
    raw = reference_trajectory(duration_s, dt_s, rng, ex.range_rad)[:n]
    max_accel = 0.85 * k_gain * AMPLIFIER_LIMIT_V / j
    ref_p, ref_v, ref_a = shape_reference(raw, dt_s, 6.0, max_accel)
    wn = ex.bandwidth_rad_s
    pole = math.exp(-2 * math.pi * 150.0 * dt_s)
    gains = np.array(
        [
            wn * wn * j / k_gain,
            2 * 0.7 * wn * j / k_gain,
            j / k_gain,
            true_model.params["viscous.b"] / k_gain,
            true_model.params["coulomb.torque"] / k_gain,
            pole,
        ]
    )
    dither = rng.normal(0.0, ex.dither_v, n)
    a = math.exp(-dt_s / ex.disturbance_tau_s)
    white = rng.normal(0.0, ex.disturbance_nm * math.sqrt(1 - a * a), n)
    dist = _ar1(white, a)
    u, theta, _ = _closed_loop(P, dt_s, ref_p, ref_v, ref_a, gains, dither, dist, initial_state())
    effects = ",".join(true_model.effects) or "none"
    return Measurement(
        np.arange(n, dtype=float) * dt_s, u, theta, f"twin closed loop (hidden: {effects}; seed {seed})"
    )


@njit(cache=True)
def _ar1(white: FloatArray, a: float) -> FloatArray:
    out = np.empty_like(white)
    s = 0.0
    for k in range(white.shape[0]):
        s = a * s + white[k]
        out[k] = s
    return out


# Physical ranges of hidden effects for tests and the benchmark scorecard (pan-like axis).
# Values relative to the base model are scaled by it: "fc" × Coulomb torque, "b" × viscous.
HIDDEN_RANGES: Mapping[str, Mapping[str, tuple[float, float, str]]] = {
    "coulomb_asymmetry": {"negative": (1.25, 1.6, "fc")},
    "viscous_asymmetry": {"negative": (2.5, 4.0, "b")},
    "offset": {"torque": (0.012, 0.03, "signed")},
    "stiction": {"static_torque": (1.4, 2.0, "fc"), "velocity": (0.02, 0.08, "abs")},
    "gravity": {"torque": (0.03, 0.08, "abs"), "phase": (-math.pi, math.pi, "abs")},
    "delay": {"seconds": (0.004, 0.02, "abs")},
    "saturation": {"limit": (2.5, 6.0, "abs")},
    "ripple": {
        "amplitude": (0.012, 0.03, "abs"),
        "cycles_per_rev": (8, 40, "int"),
        "phase": (-math.pi, math.pi, "abs"),
    },
    "backlash": {"width": (0.006, 0.02, "abs")},
    "compliance": {"frequency": (8.0, 30.0, "abs"), "damping": (0.05, 0.2, "abs")},
}


def random_hidden_model(axis: str, effects: Iterable[str], seed: int) -> AxisModel:
    """The seed's ``axis`` model with ``effects`` at random parameters drawn from HIDDEN_RANGES."""
    rng = np.random.default_rng(seed)
    base = AxisModel.for_axis(axis)
    names = list(effects)
    values: dict[str, float] = {}
    for name in names:
        if name not in HIDDEN_RANGES:
            raise ConfigError(
                f"no physical range for hidden effect {name!r}; known: {', '.join(HIDDEN_RANGES)}"
            )
        for param, (lo, hi, how) in HIDDEN_RANGES[name].items():
            v = float(rng.uniform(lo, hi))
            if how == "fc":
                v *= base.params["coulomb.torque"]
            elif how == "b":
                v *= base.params["viscous.b"]
            elif how == "signed":
                v *= float(rng.choice([-1.0, 1.0]))
            elif how == "int":
                v = float(rng.integers(int(lo), int(hi) + 1))
            values[f"{name}.{param}"] = v
    return AxisModel.for_axis(axis, names, values)


__all__ = [
    "HIDDEN_RANGES",
    "Excitation",
    "generate_measurement",
    "random_hidden_model",
    "reference_trajectory",
    "shape_reference",
]
