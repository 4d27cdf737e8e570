"""Saturation: the drive clips the command below what the controller asked for; and the drive's rail."""

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from tracker.plant.effects.base import Effect, Param
from tracker.units import AMPLIFIER_LIMIT_V


def drive_rail_v(u_v: ArrayLike) -> float:
    """The rail (V) of the drive that received the command ``u_v`` (any shape).

    The rig's amplifier (:data:`tracker.units.AMPLIFIER_LIMIT_V`, ±10 V), or the largest |u| the
    command asks for when that is more. A logged u is what the controller asked the drive for;
    that it asked for 11.6 V shows nothing about where the drive stops, so no model clips below
    it. A drive that delivered less than asked is a saturation, this effect's ``limit``, which
    the workbench searches and fits like any other effect.
    """
    u = np.asarray(u_v, dtype=float)
    top = float(np.max(np.abs(u))) if u.size else 0.0
    return max(AMPLIFIER_LIMIT_V, top) if np.isfinite(top) else AMPLIFIER_LIMIT_V


def clip_level_v(params: Mapping[str, float], rail_v: float) -> float:
    """The level (V) a model with ``params`` clips the command at on a drive of rail ``rail_v``
    (:func:`drive_rail_v`): its saturation's limit, never above the rail."""
    return min(params.get("saturation.limit", rail_v), rail_v)


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


# The catalogue admits any drive's limit (the rig's is ±10 V; a user's drive may be ±24 V): what
# bounds it on a log is that log's rail (:func:`drive_rail_v`), above which a limit clips nothing.
EFFECT = Effect(
    name="saturation",
    kind="input",
    description="The drive clips the command at ±limit (below what the controller asks for).",
    params=(Param("limit", "V", AMPLIFIER_LIMIT_V, 0.05, 1e6, "drive output limit"),),
    signature="error appears only when |u| is large",
    look_alikes=(),
    experiment="constant-voltage steps above the suspected limit: the acceleration stops growing with u",
)
