"""Belt compliance: a two-mass resonance between motor and load; the encoder is on the motor."""

from collections.abc import Mapping

from tracker.plant.effects.base import Effect, Param

# |H| of a second-order system has a peak (a resonance) only for a damping ratio below 1/√2.
RESONANT_DAMPING = 1.0 / 2.0**0.5
ONE_SIDED_95 = 1.645  # standard normal quantile


def unresolved(params: Mapping[str, float], stderr: Mapping[str, float]) -> str | None:
    """Why a fitted belt's resonance is not established by the data, or None.

    A belt is told by its resonance peak. With the damping ratio's standard error from the fit,
    the peak is established only when the damping is below 1/√2 with 95 % confidence; a fit
    whose damping may as well be above has shown a flexible extra state (which also fits
    friction's pre-sliding spring or the encoder's rounding), not a resonance.
    """
    zeta = params["compliance.damping"]
    se = stderr.get("compliance.damping", 0.0)
    upper = zeta + ONE_SIDED_95 * se
    if upper >= RESONANT_DAMPING:
        return (
            f"damping {zeta:.2f} ± {se:.2f}: may be {upper:.2f} (95 %), above {RESONANT_DAMPING:.3f}, "
            "where the response has no resonance peak"
        )
    return None


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
