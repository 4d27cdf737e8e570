"""How well this run pins each fitted parameter: standard error, a flag, and the experiment that pins it.

A parameter is *poorly determined* when its relative standard error exceeds
``UNCERTAIN_FRACTION`` (the fit's own threshold, 10 %), or when it ended on a bound of its
catalogue range (not at zero), where the standard error means nothing. The standard error is
the marginal one of the full covariance (the log's information on that parameter with every
other fitted beside it), so a strong correlation with another (|r| ≥ ``CORRELATION_WARNING``,
the fitter's ``correlated`` pairs) already widens it where it costs precision: the reason names
the partner, but a correlation is no flag of its own (a sharp parameter correlated with a loose
one is still pinned by the log). The experiment comes from the parameter's effect in the
catalogue (``Effect.experiment``), so it says what to record to pin that parameter.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from tracker.errors import ConfigError
from tracker.plant.effects import CATALOGUE, get_param
from tracker.workbench.fit.fit import UNCERTAIN_FRACTION


@dataclass(frozen=True, slots=True)
class ParameterCertainty:
    """One fitted parameter: value, standard error, relative error, the flag and why."""

    name: str
    value: float
    stderr: float
    poorly_determined: bool
    reason: str
    experiment: str | None

    @property
    def relative_stderr(self) -> float:
        return abs(self.stderr / self.value) if self.value != 0 else math.inf

    def to_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "value": self.value,
            "stderr": self.stderr,
            "relative_stderr": self.relative_stderr,
            "poorly_determined": self.poorly_determined,
            "reason": self.reason,
            "experiment": self.experiment,
        }


# A value within this fraction of a bound's size from it is "at" the bound.
AT_BOUND_FRACTION = 1e-3


def _at_bound(name: str, value: float, upper: float | None = None) -> str | None:
    """``"lower bound 0.5 Hz"`` when a fitted value sits on a catalogue bound (or on ``upper``,
    a lower one the log set), else None.

    The standard error there is one-sided and means nothing: a belt frequency pinned at its
    lowest value with a tight error is the fit leaving the model's range, not a measurement.
    "On" means within 0.1 % of the bound's own size (bounds span decades: 1e-5 to 100 rad/s).
    A bound of zero (no viscous friction, no backlash) is a physical value and is left to the
    relative error, which is infinite there anyway; a phase wraps and has no bound.
    """
    if name.endswith(".phase"):
        return None
    try:
        prm = get_param(name)
    except ConfigError:
        return None
    if not math.isfinite(value):
        return None
    top = prm.upper if upper is None else min(prm.upper, upper)
    for which, bound in (("lower", prm.lower), ("upper", top)):
        if bound != 0.0 and math.isfinite(bound) and abs(value - bound) <= AT_BOUND_FRACTION * abs(bound):
            return f"{which} bound {bound:g} {prm.unit}"
    return None


def parameter_certainty(
    params: Mapping[str, float],
    stderr: Mapping[str, float],
    correlated: tuple[tuple[str, str, float], ...] = (),
    upper_bounds: Mapping[str, float] | None = None,
) -> list[ParameterCertainty]:
    """Every parameter with a standard error, flagged when this run does not pin it.

    ``upper_bounds``: bounds the log set below the catalogue's (``FitResult.upper_bounds``: a
    saturation's limit at the drive's rail, where it clips nothing)."""
    partners: dict[str, list[str]] = {}
    for a, b, c in correlated:
        partners.setdefault(a, []).append(f"{b} (r = {c:+.2f})")
        partners.setdefault(b, []).append(f"{a} (r = {c:+.2f})")
    out = []
    for name, se in stderr.items():
        value = float(params.get(name, math.nan))
        se = float(se)
        reasons = []
        rel = abs(se / value) if value else math.inf
        if not math.isfinite(se) or rel > UNCERTAIN_FRACTION:
            reasons.append(
                f"standard error {100 * rel:.0f} % of the value (above {100 * UNCERTAIN_FRACTION:.0f} %)"
                if math.isfinite(rel)
                else "no finite standard error"
            )
        bound = _at_bound(name, value, (upper_bounds or {}).get(name))
        if bound is not None:
            reasons.append(f"at the catalogue's {bound} (the fit ran out of the model's range there)")
        flagged = bool(reasons)
        if name in partners:
            reasons.append("correlated with " + ", ".join(partners[name]))
        effect = CATALOGUE.get(name.split(".")[0])
        out.append(
            ParameterCertainty(
                name,
                value,
                se,
                flagged,
                "; ".join(reasons),
                effect.experiment if effect is not None else None,
            )
        )
    return out


__all__ = ["ParameterCertainty", "parameter_certainty"]
