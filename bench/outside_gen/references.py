"""References for closed loops and voltage programs for open loops, sampled at the log's ticks.

Each returns arrays of shape (n_ticks,). Closed-loop references return (position_rad, speed_rad_s).
"""

from __future__ import annotations

import numpy as np


def s_curve_moves(
    t_s: np.ndarray, rng: np.random.Generator, span_rad: float, speed_rad_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Point-to-point moves with a cycloidal (S-curve) profile, dwells of 0.3–1.5 s between."""
    pos, vel = np.zeros_like(t_s), np.zeros_like(t_s)
    here, start = 0.0, 0.5
    while start < t_s[-1]:
        target = rng.uniform(-span_rad, span_rad)
        dist = target - here
        dur = max(abs(dist) / speed_rad_s * 2.0, 0.15)
        tau = np.clip((t_s - start) / dur, 0.0, 1.0)
        inside = (t_s >= start) & (t_s < start + dur)
        after = t_s >= start + dur
        pos[inside] = here + dist * (tau[inside] - np.sin(2 * np.pi * tau[inside]) / (2 * np.pi))
        vel[inside] = dist / dur * (1 - np.cos(2 * np.pi * tau[inside]))
        pos[after] = target
        vel[after] = 0.0
        here = target
        start += dur + rng.uniform(0.3, 1.5)
    return pos, vel


def sinusoids(t_s: np.ndarray, rng: np.random.Generator, span_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Two sines, 0.08–1.2 Hz, faded in over 1 s."""
    fade = np.clip(t_s / 1.0, 0.0, 1.0)
    pos, vel = np.zeros_like(t_s), np.zeros_like(t_s)
    for share in (0.7, 0.3):
        f = rng.uniform(0.08, 1.2) if share < 0.5 else rng.uniform(0.08, 0.5)
        a, ph = share * span_rad, rng.uniform(0, 2 * np.pi)
        pos += a * (np.sin(2 * np.pi * f * t_s + ph) - np.sin(ph))
        vel += a * 2 * np.pi * f * np.cos(2 * np.pi * f * t_s + ph)
    return pos * fade, vel * fade


def random_steps(t_s: np.ndarray, rng: np.random.Generator, span_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Raw steps to random targets every 0.6–2 s (speed reference zero)."""
    pos = np.zeros_like(t_s)
    start = 0.5
    while start < t_s[-1]:
        pos[t_s >= start] = rng.uniform(-span_rad, span_rad) * rng.choice([0.3, 1.0])
        start += rng.uniform(0.6, 2.0)
    return pos, np.zeros_like(t_s)


def voltage_steps(t_s: np.ndarray, rng: np.random.Generator, level_v: float) -> np.ndarray:
    """Steps of alternating sign, 0.4–1 × level, 0.15–0.8 s long, with rests at 0 V between some."""
    u = np.zeros_like(t_s)
    start, sign = 0.3, 1.0
    while start < t_s[-1]:
        dur = rng.uniform(0.15, 0.8)
        on = (t_s >= start) & (t_s < start + dur)
        u[on] = sign * level_v * rng.uniform(0.4, 1.0)
        sign = -sign
        start += dur + (rng.uniform(0.2, 0.6) if rng.random() < 0.5 else 0.0)
    return u


def voltage_ramps(t_s: np.ndarray, rng: np.random.Generator, level_v: float) -> np.ndarray:
    """Triangles from 0 to ±level and back (slow creeping starts), 1–3 s each, alternating sign."""
    u = np.zeros_like(t_s)
    start, sign = 0.3, 1.0
    while start < t_s[-1]:
        dur = rng.uniform(1.0, 3.0)
        tau = (t_s - start) / dur
        on = (tau >= 0) & (tau < 1)
        u[on] = sign * level_v * rng.uniform(0.6, 1.0) * (1 - np.abs(2 * tau[on] - 1))
        sign = -sign
        start += dur + rng.uniform(0.0, 0.5)
    return u


def multisine(t_s: np.ndarray, rng: np.random.Generator, level_v: float) -> np.ndarray:
    """Eight sines 0.2–6 Hz with random phases, scaled to a peak of level_v, faded in."""
    freqs = np.sort(rng.uniform(0.2, 6.0, 8))
    u = sum(np.sin(2 * np.pi * f * t_s + rng.uniform(0, 2 * np.pi)) / np.sqrt(1 + f) for f in freqs)
    u = np.asarray(u) * level_v / np.max(np.abs(u))
    return u * np.clip(t_s / 0.5, 0.0, 1.0)
