"""Backlash: a dead band between motor and load; the encoder is on the motor."""

from tracker.plant.effects.base import Effect, Param

EFFECT = Effect(
    name="backlash",
    kind="structure",
    description=(
        "Gear/belt play: the motor (and its encoder) moves freely through a dead band before "
        "it engages the load. Splits J into motor and load sides (inertia.motor_fraction)."
    ),
    params=(Param("width", "rad", 0.0, 0.0, 0.5, "whole dead band at the load"),),
    signature="encoder jumps at velocity reversals while the load lags",
    look_alikes=("stiction", "compliance"),
    experiment=(
        "slow triangle moves with a load-side sensor (or a camera on a target): lost motion at each reversal"
    ),
)
