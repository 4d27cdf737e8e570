"""The encoder: quantization of the motor-side angle to counts at the load (rounding or truncating)."""

from __future__ import annotations

import math

from numba import njit

ENC_ROUND = 0  # floor(x/q + 0.5)·q
ENC_TRUNC = 1  # floor(x/q)·q
ENCODER_MODES: dict[str, int] = {"round": ENC_ROUND, "truncate": ENC_TRUNC}


@njit(cache=True)
def quantize(x: float, q: float, mode: int) -> float:
    """Encoder reading (rad) of angle ``x`` (rad) for count ``q`` (rad); ``q <= 0``: no quantization."""
    if q <= 0.0:
        return x
    if mode == ENC_TRUNC:
        return math.floor(x / q) * q
    return math.floor(x / q + 0.5) * q


def step_for_counts(counts_per_rev: int) -> float:
    """Count size (rad) of an encoder with ``counts_per_rev`` counts per load revolution."""
    return 2.0 * math.pi / counts_per_rev
