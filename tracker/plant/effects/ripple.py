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
# of the angles a log covers, it must explain at least this share of what it explains over the
# whole range on the other half too. Over a range of one or two of its periods a sinusoid in θ is
# merely a smooth torque of position (the model's error wherever the program happens to move the
# axis fast, a bias or gravity over a small range): fitted on one half, it does not continue.
MIN_CARRY_OVER = 0.5


def _share(resid: FloatArray, columns: FloatArray, fit_on: FloatArray, test_on: FloatArray) -> float:
    """Share of ``resid``'s variance on ``test_on`` that the columns fitted on ``fit_on`` explain
    (each part keeps its own mean: a bias is not the ripple's to explain)."""
    a, b = columns[fit_on], resid[fit_on]
    coef = np.linalg.lstsq(a - a.mean(axis=0), b - b.mean(), rcond=None)[0]
    r = resid[test_on]
    e = r - columns[test_on] @ coef
    total = float(np.sum((r - r.mean()) ** 2))
    return 1.0 - float(np.sum((e - e.mean()) ** 2)) / total if total > 0 else 0.0


def carry_over(
    theta: FloatArray, residual_nm: FloatArray, cycles_per_rev: float
) -> tuple[float, float, float]:
    """How a sinusoid of ``cycles_per_rev`` in θ explains the residual torque: the share over the
    whole range (fitted and scored on all samples), and each half's share (split at the median
    angle) when fitted on the other half only."""
    th = np.asarray(theta, dtype=float)
    r = np.asarray(residual_nm, dtype=float)
    cols = np.column_stack([np.sin(cycles_per_rev * th), np.cos(cycles_per_rev * th)])
    everywhere = np.ones(th.size, dtype=bool)
    low = th < np.median(th)
    if low.sum() < 3 or (~low).sum() < 3:
        return _share(r, cols, everywhere, everywhere), 0.0, 0.0
    return _share(r, cols, everywhere, everywhere), _share(r, cols, ~low, low), _share(r, cols, low, ~low)


def not_repeating(theta: FloatArray, residual_nm: FloatArray, cycles_per_rev: float) -> str | None:
    """Why a ripple of ``cycles_per_rev`` is not seen to repeat over ``theta``, or None when it is
    (see :data:`MIN_CARRY_OVER`)."""
    whole, low, high = carry_over(theta, residual_nm, cycles_per_rev)
    if whole > 0 and min(low, high) >= MIN_CARRY_OVER * whole:
        return None
    periods = cycles_per_rev * float(np.ptp(np.asarray(theta, dtype=float))) / (2 * np.pi)
    return (
        f"not seen to repeat: over the {periods:.1f} periods the run covers, the sinusoid explains "
        f"{100 * whole:.0f} % of the residual torque, but fitted on one half of the angles only "
        f"{100 * low:.0f} % and {100 * high:.0f} % of the other half (a smooth torque of position, "
        "not a periodic one)"
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
