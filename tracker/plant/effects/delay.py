"""Transport delay of the command (amplifier, bus, computation).

A drive delay lags the whole input: the response to every change of the command, also while the
axis slides steadily. Friction's pre-sliding elasticity (LuGre's bristles) lags the response
only at rest and after reversals, and a one-sample computational latency is the loop's own; the
diagnosis tells them apart (see ``sliding.lags_while_sliding`` and ``judgement._physical``).
"""

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
