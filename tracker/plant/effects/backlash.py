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
    signature=(
        "at each reversal of the torque the encoder travels the dead band with the motor's inertia "
        "alone: a travel wider than the reading's own flicker there (a count either way, or the angle "
        "noise), which a play of that flicker's size does not explain"
    ),
    look_alikes=("stiction", "compliance", "delay"),
    experiment=(
        "slow triangle moves with a load-side sensor (or a camera on a target): lost motion at each reversal"
    ),
)
