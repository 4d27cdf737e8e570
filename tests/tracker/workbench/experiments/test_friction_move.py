"""The friction sweep's positioning move is capped for a host stall (friction_id._push_cap): a
command held for the whole stall, then the board disarmed and the axis coasting on the share of
the model's friction the cap counts on, must leave the axis short of the line. Checked against
a direct integration of J·dω/dt = K·V − c·sign ω − b·ω, not against the cap's own algebra."""

from __future__ import annotations

import math

import pytest

from tracker.plant.params import get_preset
from tracker.workbench.experiments.friction_id import (
    FRICTION_SHARE,
    LINE_MARGIN_RAD,
    STALL_S,
    _Mover,
    _push_cap,
)

DT = 0.004  # the live sweep's sample period at 250 Hz


def mover(axis: str) -> _Mover:
    p = get_preset(axis)
    lim = p.soft_limit_rad
    return _Mover(p.gain_nm_per_v, p.inertia_kg_m2, p.coulomb_nm, (-lim, lim), STALL_S)


def excursion(mv: _Mover, viscous: float, v0: float, volts: float, hold_s: float) -> float:
    """How far outward the axis goes: ``volts`` held for ``hold_s``, then 0 V until it stops;
    friction at the share the cap counts on (the worst the cap allows for)."""
    c, b = FRICTION_SHARE * mv.coulomb, FRICTION_SHARE * viscous
    x, w, t, h = 0.0, v0, 0.0, 1e-5
    while True:
        u = volts if t < hold_s else 0.0
        drive = mv.gain * u
        if w == 0.0 and abs(drive) <= c:
            if t >= hold_s:
                return x
            acc = 0.0
        else:
            sign = math.copysign(1.0, w) if w != 0.0 else math.copysign(1.0, drive)
            acc = (drive - c * sign - b * w) / mv.inertia
        w_new = w + acc * h
        if t >= hold_s and w > 0.0 >= w_new:
            return x
        if w * w_new < 0.0 and t < hold_s:
            w_new = 0.0  # friction does not reverse the motion by itself within a step
        x += 0.5 * (w + w_new) * h
        w, t = w_new, t + h
        if t > 30.0:
            raise AssertionError("did not stop")


@pytest.mark.parametrize("axis", ["pan", "tilt"])
@pytest.mark.parametrize("v0", [0.0, 0.5, 2.0, 4.0])
@pytest.mark.parametrize("room", [0.1, 0.3, 1.0, 2.5])
def test_a_capped_command_held_through_a_stall_stops_short_of_the_line(
        axis: str, v0: float, room: float) -> None:
    mv, b = mover(axis), get_preset(axis).viscous_nm_s_per_rad
    volts = max(-10.0, min(10.0, _push_cap(mv, v0, room, DT)))
    if volts < _push_cap(mv, v0, room, DT) - 1e-9:
        pytest.skip("beyond what the amplifier can brake: the line ahead cannot be held from here")
    reach = excursion(mv, b, v0, volts, STALL_S + DT)
    assert reach <= room - LINE_MARGIN_RAD + 1e-4, (volts, reach)
    # ...and not needlessly timid: 20 % more outward push would go further than the room allows
    # wherever the cap is a push above the friction it has to overcome.
    more = volts + 0.2 * abs(volts) + 0.05
    if more <= 10.0 and volts > mv.coulomb / mv.gain:
        assert excursion(mv, b, v0, more, STALL_S + DT) > room - LINE_MARGIN_RAD - 0.02 * room


def test_far_from_the_line_the_cap_lets_the_axis_start() -> None:
    for axis in ("pan", "tilt"):
        mv = mover(axis)
        assert _push_cap(mv, 0.0, 1.0, DT) > mv.coulomb / mv.gain  # above break-away at rest
        assert _push_cap(mv, 6.0, 0.2, DT) < 0.0  # fast and near: it must brake
