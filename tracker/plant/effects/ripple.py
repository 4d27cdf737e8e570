"""Position-periodic torque ripple (cogging, gear mesh): amplitude·sin(n·θ + phase)."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """τ = A·sin(n·θ + φ), n cycles per load revolution."""
    th = np.asarray(theta, dtype=float)
    n = params["ripple.cycles_per_rev"]
    return params["ripple.amplitude"] * np.sin(n * th + params["ripple.phase"])


# A ripple is a torque of position that repeats: the same wherever the axis is. Fitted on one half
# of the angles a log covers, its sinusoid must explain at least this share of what the other
# half's own fit explains there (that is, the two halves' amplitude-and-phase vectors differ by
# less than about 70 % of either). Over a range of one or two of its periods a sinusoid in θ is
# merely a smooth torque of position (the model's error wherever the program happens to move the
# axis fast, a bias or gravity over a small range): fitted on one half, it does not continue.
MIN_CARRY_OVER = 0.5


def _explained(resid: FloatArray, columns: FloatArray, coef: FloatArray) -> float:
    """Variance of ``resid`` that ``columns @ coef`` removes (each keeps its own mean: a bias is
    not the ripple's to explain)."""
    e = resid - columns @ coef
    return float(np.sum((resid - resid.mean()) ** 2) - np.sum((e - e.mean()) ** 2))


def carry_over(theta: FloatArray, residual_nm: FloatArray, cycles_per_rev: float) -> tuple[float, float]:
    """For each half of the angles (split at the median angle): the residual torque a sinusoid of
    ``cycles_per_rev`` fitted on the *other* half explains there, as a share of what the sinusoid
    fitted on that half itself explains (1: the same ripple on both halves; at most 1, and held at
    -1 below: a fit that adds more than it removes)."""
    th = np.asarray(theta, dtype=float)
    r = np.asarray(residual_nm, dtype=float)
    cols = np.column_stack([np.sin(cycles_per_rev * th), np.cos(cycles_per_rev * th)])
    low = th < np.median(th)
    halves = (low, ~low)
    if min(int(h.sum()) for h in halves) < 3:
        return 0.0, 0.0
    coefs = []
    for h in halves:
        a, b = cols[h], r[h]
        coefs.append(np.linalg.lstsq(a - a.mean(axis=0), b - b.mean(), rcond=None)[0])
    out = []
    for i, h in enumerate(halves):
        own = _explained(r[h], cols[h], coefs[i])
        out.append(max(_explained(r[h], cols[h], coefs[1 - i]) / own, -1.0) if own > 0 else 0.0)
    return out[0], out[1]


def not_repeating(theta: FloatArray, residual_nm: FloatArray, cycles_per_rev: float) -> str | None:
    """Why a ripple of ``cycles_per_rev`` is not seen to repeat over ``theta``, or None when it is
    (see :data:`MIN_CARRY_OVER`)."""
    low, high = carry_over(theta, residual_nm, cycles_per_rev)
    if min(low, high) >= MIN_CARRY_OVER:
        return None
    periods = cycles_per_rev * float(np.ptp(np.asarray(theta, dtype=float))) / (2 * np.pi)
    return (
        f"not seen to repeat: over the {periods:.1f} periods the run covers, the sinusoid fitted on "
        f"one half of the angles explains only {100 * low:.0f} % and {100 * high:.0f} % of what the "
        "other half's own fit explains there (a smooth torque of position, not a periodic one)"
    )


EFFECT = Effect(
    name="ripple",
    kind="torque",
    description="Torque that repeats with position, n times per revolution (cogging, gears).",
    params=(
        Param("amplitude", "N·m", 0.0, 0.0, 1e6, "ripple torque amplitude"),
        Param("cycles_per_rev", "1/rev", 21.0, 1.0, 500.0, "periods per load revolution"),
        Param("phase", "rad", 0.0, -np.pi, np.pi, "phase of the ripple"),
    ),
    signature="residual is periodic in θ",
    torque_nm=torque_nm,
    look_alikes=("gravity",),
    experiment=(
        "a slow constant-speed move over a full revolution (or the widest range): torque ripple vs θ"
    ),
)
