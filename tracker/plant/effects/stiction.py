"""Static friction with a Stribeck curve: break-away torque above Coulomb at low speed."""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects.base import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """Extra friction over Coulomb: (Fs − Fc)·exp(−(ω/vs)²)·sign(ω) (Stribeck)."""
    w = np.asarray(omega, dtype=float)
    extra = params["stiction.static_torque"] - params["coulomb.torque"]
    return np.asarray(extra * np.exp(-((w / params["stiction.velocity"]) ** 2)) * np.sign(w), dtype=float)


# Below this excess of break-away over Coulomb the curve is the kinetic friction's Stribeck dip
# (a few per cent is ordinary for lubricated gears), not stick-slip that compensation must treat.
SMALL_EXCESS_RATIO = 0.1


def negligible(params: Mapping[str, float]) -> str | None:
    """Why a fitted break-away is too close to Coulomb to count as missing stiction, or None."""
    fc = params["coulomb.torque"]
    excess = params["stiction.static_torque"] - fc
    if fc > 0 and excess < SMALL_EXCESS_RATIO * fc:
        return (
            f"break-away only {100 * excess / fc:.1f} % above Coulomb (under "
            f"{100 * SMALL_EXCESS_RATIO:.0f} %): a Stribeck dip of the kinetic friction, not stick-slip"
        )
    return None


def negligible_at_rest(coulomb_nm: float, excess_upper_nm: float) -> str | None:
    """Why static friction measured directly is too small to count, or None.

    ``excess_upper_nm`` is the upper end of the 95 % interval of the break-away torque over
    Coulomb measured on starts from rest (the direct measure of static friction). When even that
    stays under the Stribeck dip's share of Coulomb, a larger break-away fitted by simulation is
    the model's Karnopp stick fitting something else (a Stribeck curve's dip, creep), not
    static friction the axis has.
    """
    if coulomb_nm > 0 and excess_upper_nm < SMALL_EXCESS_RATIO * coulomb_nm:
        return (
            f"break-away measured from rest at most {100 * excess_upper_nm / coulomb_nm:.1f} % "
            f"above Coulomb (95 % bound, under {100 * SMALL_EXCESS_RATIO:.0f} %): a Stribeck dip "
            "of the kinetic friction, not stick-slip"
        )
    return None


EFFECT = Effect(
    name="stiction",
    kind="torque",
    description=(
        "Break-away (static) friction above Coulomb that decays with speed (Stribeck); "
        "the axis sticks until the applied torque exceeds it (Karnopp)."
    ),
    params=(
        Param("static_torque", "N·m", 0.08, 0.0, 1e6, "break-away torque at rest"),
        Param("velocity", "rad/s", 0.05, 1e-5, 100.0, "Stribeck velocity"),
    ),
    signature="error concentrates at low speed and at starts from rest",
    torque_nm=torque_nm,
    look_alikes=("delay", "backlash"),
    experiment=(
        "friction-ID sweep (tracker friction-id): break-away voltage on a slow ramp above the "
        "Coulomb intercept shows stiction (a delay does not change it)"
    ),
    negligible=negligible,
)
