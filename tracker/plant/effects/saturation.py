"""Amplifier saturation below the nominal ±10 V."""

from tracker.plant.effects.base import Effect, Param

EFFECT = Effect(
    name="saturation",
    kind="input",
    description="The amplifier clips the command at ±limit (below its nominal ±10 V).",
    params=(Param("limit", "V", 10.0, 0.05, 10.0, "amplifier output limit"),),
    signature="error appears only when |u| is large",
    look_alikes=(),
    experiment="constant-voltage steps above the suspected limit: the acceleration stops growing with u",
)
