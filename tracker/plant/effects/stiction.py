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


# Static friction the break-away from rest establishes by itself: the lower 95 % bound of the
# excess over the Coulomb torque of sliding must be at least this share of it (well past a
# Stribeck dip; the clean logs of an independent generator stay under 6 %, hidden stiction is
# 50-120 %).
ESTABLISHED_EXCESS_RATIO = 0.25


def established_at_rest(sliding_coulomb_nm: float, excess_nm: float, excess_lower_nm: float) -> str | None:
    """Evidence that static friction is established by the break-away from rest alone, or None.

    ``excess_nm`` is the break-away torque measured on starts from rest (the torque applied when
    the axis broke away) over ``sliding_coulomb_nm``, the Coulomb torque the moving data give (a
    torque regression: not the model's, which a missing stiction biases); ``excess_lower_nm`` its
    lower 95 % bound. A prediction a few tens of ms ahead from measured states barely sees static
    friction (it changes only when a stuck axis starts), so where the axis holds far more than
    Coulomb at rest this direct measure decides. A delay leaves it at Coulomb (the late torque
    raises the break-away only in proportion to the command's rate, which the break-away
    analysis regresses apart).
    """
    if sliding_coulomb_nm <= 0 or excess_lower_nm < ESTABLISHED_EXCESS_RATIO * sliding_coulomb_nm:
        return None
    return (
        f"break-away measured from rest {100 * excess_nm / sliding_coulomb_nm:.0f} % above the "
        f"Coulomb torque of sliding (95 % lower bound {100 * excess_lower_nm / sliding_coulomb_nm:.0f} %, "
        f"over {100 * ESTABLISHED_EXCESS_RATIO:.0f} %): static friction, whatever the short prediction shows"
    )


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
