"""Base effect: the axis inertia J (load coordinates)."""

from tracker.plant.effects.base import Effect, Param

EFFECT = Effect(
    name="inertia",
    kind="base",
    description="Rotating inertia seen at the load: J = J_load + N² J_motor (seed eq. 3.2).",
    params=(
        Param("J", "kg·m²", 0.0028 + 6.3**2 * 1.6e-6, 1e-8, 1e5, "total inertia at the load"),
        Param(
            "motor_fraction",
            "1",
            0.15,
            0.01,
            0.9,
            "share of J on the motor side of a belt or backlash (used only by two-mass effects)",
            fit=False,
        ),
    ),
    signature="errors scale with acceleration",
    experiment="steps or a chirp with large accelerations: J is what separates torque from acceleration",
)
