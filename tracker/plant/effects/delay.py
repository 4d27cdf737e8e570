"""Transport delay of the command (amplifier, bus, computation)."""

from tracker.plant.effects.base import Effect, Param

EFFECT = Effect(
    name="delay",
    kind="input",
    description="The amplifier applies the command late by a fixed time.",
    params=(Param("seconds", "s", 0.0, 0.0, 0.2, "transport delay"),),
    signature="input–residual cross-correlation peaks at a positive lag",
    look_alikes=("stiction", "compliance"),
    experiment=(
        "small fast steps or a chirp while moving: the lag of the response to the command; the "
        "constant-voltage sweep does not show a delay"
    ),
)
