"""The camera's speed law toward a soft limit: room to stop even when a command comes late."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.drivers.camera_profiles import get_profile, profile_names
from tracker.drivers.camera_servo import BRAKE_FRACTION, axis_drive


@pytest.mark.parametrize("name", profile_names())
def test_a_drive_toward_a_limit_stops_inside_it_after_a_missed_period(name: str) -> None:
    """Bug: a speed drive planned to stop after latency + one period; a host under load sent the
    stop one period late and the emulated head ran 0.007 deg past the limit. Whatever the start,
    the speed chosen must allow one more late period and braking at the planned deceleration."""
    prof = get_profile(name)
    period_s, latency_s = 0.04, 0.03
    hi = math.radians(90.0)
    brake = BRAKE_FRACTION * prof.accel_rad_s2
    for axis in ("pan", "tilt"):
        for room_deg in np.geomspace(1e-3, 20.0, 200):
            pos = hi - math.radians(float(room_deg))
            for rate in (prof.max_speed_rad_s(axis), prof.code_speed_rad_s(axis, 1)):
                drive = axis_drive(prof, axis, position_rad=pos, target_rad=None, rate_rad_s=rate,
                                   limits_rad=(-hi, hi), period_s=period_s, latency_s=latency_s)
                v = drive.speed_rad_s
                if v <= 0.0:
                    continue
                travel = v * (latency_s + 2.0 * period_s) + v * v / (2.0 * brake)
                assert pos + travel <= hi + 1e-12, (axis, room_deg, v)
