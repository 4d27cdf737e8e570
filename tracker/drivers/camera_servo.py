"""The speed law that steers a PTZ head toward a target through its speed table.

Every command period, per axis (console frame, rad):

    v = v_ff + (target - θ̂) / τ,     τ = max(2·period, 0.1 s)

where θ̂ is the last reported angle advanced by the commanded speed over its age and v_ff the
target's own rate. Inside a dead band of ``max(1 count, v₁·period)`` (v₁ the slowest code's
speed) around a target that does not move, the axis stops. Toward the target, and toward a
soft limit, the speed is capped so that, after the dead time T = latency + period and braking
at half the head's acceleration a (slack for jitter and the head's own lag), it can stop
there: v ≤ a'·(−T + sqrt(T² + 2·room/a')), a' = a/2 (plus |v_ff| toward a moving target);
without the first cap a 30° step overshot by 15°, and braking at the full a ran 0.08° past a
limit on the emulator. The speed is then
rounded *down* to the speed table (never faster than asked), at least code 1 outside the
dead band when the limit allows it.

All of that relies on the host's next commands arriving. :func:`handoff_room_rad` is where
the driver stops relying on them: within that distance of a limit (the stopping distance at
the planned deceleration, plus the dead time and two more late periods, plus the dead band)
it hands the rest of the drive to the camera's own position loop (an absolute move to the
limit or the target), which stops there by itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tracker.drivers.camera_profiles import CameraProfile


@dataclass(frozen=True, slots=True)
class AxisDrive:
    """One axis' command: ``code`` (1.. in the speed table) and ``direction`` (+1, -1 or 0 =
    stop, console frame); ``speed_rad_s`` is the table's speed, signed (0 when stopped)."""

    code: int
    direction: int
    speed_rad_s: float


STOP = AxisDrive(1, 0, 0.0)
BRAKE_FRACTION = 0.5  # of the profile's acceleration, counted on for stopping


def dead_band_rad(profile: CameraProfile, axis: str, period_s: float) -> float:
    """Where the servo stops around a still target (rad)."""
    return max(profile.rad_per_count, profile.code_speed_rad_s(axis, 1) * period_s)


def limit_speed_rad_s(room_rad: float, accel_rad_s2: float, dead_time_s: float) -> float:
    """The fastest speed that still stops within ``room_rad`` after ``dead_time_s`` of
    reaction and braking at ``accel_rad_s2`` (0 when there is no room)."""
    if room_rad <= 0.0:
        return 0.0
    t = dead_time_s
    return accel_rad_s2 * (-t + math.sqrt(t * t + 2.0 * room_rad / accel_rad_s2))


HANDOFF_LATE_PERIODS = 2  # command periods the hand-off allows for, beyond latency + one period


def handoff_room_rad(profile: CameraProfile, axis: str, speed_rad_s: float, *,
                     period_s: float, latency_s: float) -> float:
    """How close to a limit (rad) a drive at ``speed_rad_s`` is handed to the camera's position
    loop: ``v²/(2·a') + v·(latency + (1 + HANDOFF_LATE_PERIODS)·period) + dead band``, a' the
    planned deceleration (one late period more than :func:`axis_drive` leaves room for, so the
    hand-off comes before the speed law starts braking)."""
    v = abs(speed_rad_s)
    brake = BRAKE_FRACTION * profile.accel_rad_s2
    dead_time = latency_s + (1 + HANDOFF_LATE_PERIODS) * period_s
    return v * v / (2.0 * brake) + v * dead_time + dead_band_rad(profile, axis, period_s)


def axis_drive(
    profile: CameraProfile,
    axis: str,
    *,
    position_rad: float,
    target_rad: float | None,
    rate_rad_s: float,
    limits_rad: tuple[float, float],
    period_s: float,
    latency_s: float,
) -> AxisDrive:
    """The drive command for one axis (see the module docstring). ``target_rad`` None means a
    pure speed drive at ``rate_rad_s``."""
    dead = dead_band_rad(profile, axis, period_s)
    slowest = profile.code_speed_rad_s(axis, 1)
    dead_time = latency_s + period_s
    brake = BRAKE_FRACTION * profile.accel_rad_s2
    braking = math.inf
    if target_rad is None:
        v = rate_rad_s
        if abs(v) < 0.5 * slowest:
            return STOP
    else:
        e = target_rad - position_rad
        if abs(e) < dead and abs(rate_rad_s) < 0.5 * slowest:
            return STOP
        v = rate_rad_s + e / max(2.0 * period_s, 0.1)
        if v * e > 0:
            braking = abs(rate_rad_s) + limit_speed_rad_s(abs(e) - 0.5 * dead, brake, dead_time)
    lo, hi = limits_rad
    room = hi - position_rad if v > 0 else position_rad - lo
    # Toward a soft limit the stop command may itself come one period late (a host under load
    # misses a command period now and then; the driver counts them): plan for that too. Without
    # it a late cycle ran the emulated head 0.007 deg past the limit at the slowest code.
    allowed = limit_speed_rad_s(room - 0.5 * dead, brake, dead_time + period_s)
    speed = min(abs(v), allowed, braking, profile.max_speed_rad_s(axis))
    if speed < slowest:
        if allowed < slowest or (target_rad is None and speed < 0.5 * slowest):
            return STOP
        speed = slowest
    code = profile.speed_code(axis, speed)
    direction = 1 if v > 0 else -1
    return AxisDrive(code, direction, direction * profile.code_speed_rad_s(axis, code))
