"""Amplifier saturation below the nominal ±10 V."""

from tracker.plant.effects.base import Effect, Param


def not_where_clipped(error_share: float, time_share: float) -> str | None:
    """Why a clip level is no saturation, or None when it may be one.

    A clip changes the torque only where the command goes beyond it, so the model's error (the
    residual torque's energy without the clip) must gather there: the clipped samples must carry a
    larger share of it than their share of the time. A "clip" whose samples carry no more than
    their share (a level under half of the commands, crediting it with a torque missing all
    through the run: a static friction that the loop's integrator pushes through) explains
    nothing a clip would."""
    if time_share <= 0.0 or error_share > time_share:
        return None
    return (
        f"not where the command is clipped: the {100 * time_share:.0f} % of the time beyond the "
        f"level carry {100 * error_share:.0f} % of the residual torque, no more than their share"
    )


EFFECT = Effect(
    name="saturation",
    kind="input",
    description="The amplifier clips the command at ±limit (below its nominal ±10 V).",
    params=(Param("limit", "V", 10.0, 0.05, 10.0, "amplifier output limit"),),
    signature="error appears only when |u| is large",
    look_alikes=(),
    experiment="constant-voltage steps above the suspected limit: the acceleration stops growing with u",
)
