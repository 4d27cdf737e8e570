"""Encoder quantization: the angle is reported in whole counts."""

from tracker.plant.effects.base import Effect, Param

# Pittman GM8724 encoder: 500 lines, x4 decoding, on the motor, through 6.3:1 gear and 2.7:1 pulley.
SEED_ENCODER_STEP_RAD = 2.0 * 3.141592653589793 / (4 * 500 * 6.3 * 2.7)

EFFECT = Effect(
    name="quantization",
    kind="sensor",
    description="The encoder reports the angle in whole counts of `step`.",
    params=(Param("step", "rad", SEED_ENCODER_STEP_RAD, 0.0, 0.1, "one encoder count at the load"),),
    signature="residual is white and within ±step/2",
)
