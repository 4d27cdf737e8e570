"""Belt compliance: a two-mass resonance between motor and load; the encoder is on the motor."""

from tracker.plant.effects.base import Effect, Param

EFFECT = Effect(
    name="compliance",
    kind="structure",
    description=(
        "Elastic belt between motor and load: a resonance at `frequency` with damping ratio "
        "`damping`. Splits J into motor and load sides (inertia.motor_fraction)."
    ),
    params=(
        Param("frequency", "Hz", 20.0, 0.5, 300.0, "two-mass resonance frequency"),
        Param("damping", "1", 0.1, 0.001, 2.0, "damping ratio of the resonance"),
    ),
    signature="a resonance peak in the residual spectrum",
    look_alikes=("backlash", "delay"),
    experiment="a chirp or small steps at 5–100 Hz: a resonance peak in the encoder's frequency response",
)
