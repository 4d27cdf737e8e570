"""A site's own effect: the drag torque of a cable that winds up as the axis turns.

The physics
-----------
The camera's power and video cable runs from the fixed base through the pan (or tilt) axis to
the head. It is laid slack at one angle, θ0. Turned away from there, the cable bends and twists
and pulls the head back like a soft torsion spring, k·(θ − θ0); its weight and the rub of its
loop against the housing add a bias that does not depend on the angle, T0. Quasi-statically::

    τ_cable(θ) = T0 + k·(θ − θ0)                      (resisting: J θ'' = K u − … − τ_cable)

* ``torque``    T0, N·m: the bias at θ0 (either sign), bounds ±10 N·m.
* ``stiffness`` k, N·m/rad: the spring rate of the winding cable, ≥ 0 (a cable pulls back, it
  never pushes further), at most 10 N·m/rad.
* ``theta0``    θ0, rad: where the cable lies slack. *Not fitted*: the data see T0 + k·(θ − θ0)
  as a whole (moving θ0 by δ moves T0 by −k·δ), so set it to where you routed the cable
  (``--set cable_drag.theta0=0.3``) and read T0 as the torque there.

The torque depends on the angle only, as every effect outside the built-ins must: the
simulator tabulates it, the diagnosis differentiates it with respect to its parameters (both
are linear here, so the regression finds them in one step; no search grid is needed).

Look-alikes: a bias torque (``offset``) is the constant part, and over a small range gravity's
sin(θ + φ) is a straight line too; a cable winds up over the travel and does not reverse at
±90° as gravity does. The experiment that tells them apart: hold the axis at several angles
across its travel and log the holding command (or, motor off, measure the torque that holds it
with a spring balance on a lever): the holding torque of a cable rises linearly with θ, that of
an unbalance follows sin θ, a bias torque stays the same; approach each angle from both
directions, because friction flips with the direction of approach and the cable does not.

Using it
--------
Make the module importable (or name its file) and tell the engine about it, then use the name
like any effect::

    TRACKER_EFFECTS=examples/effects/cable_drag.py tracker model diagnose run.csv --axis pan
    TRACKER_EFFECTS=examples/effects/cable_drag.py tracker model fit run.csv --axis pan --effects cable_drag

or in Python, ``tracker.plant.effects.register_effect(cable_drag.EFFECT)`` (importing this
module is not enough when it is not named in ``TRACKER_EFFECTS``).
"""

from collections.abc import Mapping

import numpy as np

from tracker.plant.effects import Effect, FloatArray, Param


def torque_nm(params: Mapping[str, float], theta: FloatArray, omega: FloatArray) -> FloatArray:
    """τ = T0 + k·(θ − θ0), N·m, shape of ``theta`` (the velocity plays no part)."""
    th = np.asarray(theta, dtype=float)
    return params["cable_drag.torque"] + params["cable_drag.stiffness"] * (th - params["cable_drag.theta0"])


EFFECT = Effect(
    name="cable_drag",
    kind="torque",
    description="A cable that winds up as the axis turns: a bias plus a spring, T0 + k·(θ − θ0).",
    params=(
        Param("torque", "N·m", 0.0, -10.0, 10.0, "bias torque of the cable at theta0"),
        Param("stiffness", "N·m/rad", 0.0, 0.0, 10.0, "spring rate of the winding cable"),
        Param("theta0", "rad", 0.0, -2 * np.pi, 2 * np.pi, "angle where the cable lies slack", fit=False),
    ),
    signature="residual torque rises in a straight line with θ",
    torque_nm=torque_nm,
    look_alikes=("offset", "gravity"),
    experiment=(
        "hold the axis at several angles across its travel, approaching each from both directions, "
        "and log the holding command (or measure the holding torque with the motor off): a cable's "
        "rises linearly with θ, an unbalance's follows sin θ, a bias torque's stays the same"
    ),
    evidence="{torque:+.3g} N·m at θ0 = {theta0:.2f} rad, rising {stiffness:.3g} N·m/rad with the angle",
)
