"""The twin of a PTZ camera's head: speed-table drives, position moves with an acceleration
limit, backlash at the load, quantized position counts, a zoom and presets.

Everything is in the camera's VISCA frame (pan positive right, tilt positive up), in radians;
counts appear only where VISCA does (:meth:`CameraTwin.position_counts`). Time advances by
:meth:`CameraTwin.step`; the emulator calls it on its clock.

Per axis, each step (explicit, dt ≤ 10 ms): the commanded speed v* is the drive's speed code
(from the profile's table) or, for a position move, ``sign(e)·min(v_max, sqrt(2·a·|e|))``
(the fastest speed that can still stop at the target); the speed follows v* at most ``a·dt``
per step; the motor angle integrates it and stops at the mechanical range. The load follows
the motor through a dead band of ``backlash`` (it lags by up to the play after a reversal).

Pan-tilt limits (VISCA Pan-tiltLimitSet, :meth:`CameraTwin.set_limit`) narrow the range the way
a camera's own limits do: a position move's target is clamped to them, and a drive toward one
is slowed to the fastest speed that still stops there at the head's own acceleration
(``sqrt(2·a·room)``, less a step's reaction), so the head comes to rest on the limit whether
or not another command arrives.
A head that cannot stop in time (a limit set just ahead of it at speed) passes it and brakes;
a head outside its limits may move back in, never further out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from tracker.drivers.camera_profiles import CameraProfile
from tracker.errors import DataError

AXES = ("pan", "tilt")

# A position move is done when within this many counts of its target and slow.
ARRIVAL_COUNTS = 0.5


@dataclass(slots=True)
class AxisTwin:
    """One axis of the head (VISCA frame, rad)."""

    lo_rad: float
    hi_rad: float
    accel_rad_s2: float
    backlash_rad: float
    motor_rad: float = 0.0
    load_rad: float = 0.0
    speed_rad_s: float = 0.0
    mode: str = "idle"  # idle | drive | position
    drive_rad_s: float = 0.0
    target_rad: float = 0.0
    max_rad_s: float = 0.0
    limit_lo_rad: float | None = None  # the camera's own pan-tilt limits (None: none set)
    limit_hi_rad: float | None = None

    def bounds(self) -> tuple[float, float]:
        """Where the head may go: the mechanical range within the pan-tilt limits."""
        lo = self.lo_rad if self.limit_lo_rad is None else max(self.lo_rad, self.limit_lo_rad)
        hi = self.hi_rad if self.limit_hi_rad is None else min(self.hi_rad, self.limit_hi_rad)
        return lo, hi

    def stop_speed_rad_s(self, room_rad: float, dt_s: float) -> float:
        """The fastest speed from which the head, stepping ``dt_s`` at a time, still stops
        within ``room_rad``: ``v·1.5·dt + v²/(2a) = room`` (one step to react, half a step of
        the discrete braking), 0 without room (inf with infinite room)."""
        if room_rad <= 0.0:
            return 0.0
        if math.isinf(room_rad):
            return math.inf
        a, t = self.accel_rad_s2, 1.5 * dt_s
        return a * (-t + math.sqrt(t * t + 2.0 * room_rad / a))

    def step(self, dt_s: float, arrival_rad: float) -> bool:
        """Advance ``dt_s``; True when a position move arrived during this step."""
        arrived = False
        lo, hi = self.bounds()
        # Only the pan-tilt limits brake a drive; the mechanical range stops it dead, as before.
        set_lo = -math.inf if self.limit_lo_rad is None else lo
        set_hi = math.inf if self.limit_hi_rad is None else hi
        if self.mode == "drive":
            want = self.drive_rad_s
            room = set_hi - self.motor_rad if want > 0 else self.motor_rad - set_lo
            want = math.copysign(min(abs(want), self.stop_speed_rad_s(room, dt_s)), want)
        elif self.mode == "position":
            self.target_rad = min(max(self.target_rad, lo), hi)
            e = self.target_rad - self.motor_rad
            want = math.copysign(min(self.max_rad_s, math.sqrt(2.0 * self.accel_rad_s2 * abs(e))), e)
            if abs(e) <= max(arrival_rad, abs(self.speed_rad_s) * dt_s):
                self.motor_rad, self.speed_rad_s, self.mode, want = self.target_rad, 0.0, "idle", 0.0
                arrived = True
        else:
            want = 0.0
        dv = self.accel_rad_s2 * dt_s
        before = self.motor_rad
        self.speed_rad_s += min(max(want - self.speed_rad_s, -dv), dv)
        self.motor_rad += self.speed_rad_s * dt_s
        for limit, side in ((set_hi, 1.0), (set_lo, -1.0)):
            # The camera's loop arrives on a limit it was braking for (within one step's speed
            # change of the stopping profile); faster than that it passes and brakes beyond.
            room = side * (limit - before)
            crossed = side * (self.motor_rad - limit) > 0.0 and room >= 0.0
            if crossed and abs(self.speed_rad_s) <= self.stop_speed_rad_s(room, dt_s) + 2.0 * dv:
                self.motor_rad, self.speed_rad_s = limit, 0.0
        if not self.lo_rad <= self.motor_rad <= self.hi_rad:
            self.motor_rad = min(max(self.motor_rad, self.lo_rad), self.hi_rad)
            self.speed_rad_s = 0.0
        half = 0.5 * self.backlash_rad
        self.load_rad = min(max(self.load_rad, self.motor_rad - half), self.motor_rad + half)
        return arrived


@dataclass(slots=True)
class CameraTwin:
    """The whole camera: two axes, zoom, presets, power (see the module docstring)."""

    profile: CameraProfile
    axes: dict[str, AxisTwin] = field(init=False)
    zoom: float = 0.0
    zoom_target: float | None = None
    zoom_rate: float = 0.0  # counts/s while driving the zoom
    presets: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    power_on: bool = True

    def __post_init__(self) -> None:
        p = self.profile
        self.axes = {}
        for axis in AXES:
            lo, hi = sorted(p.sign[axis] * v for v in p.range_rad[axis])  # console -> VISCA frame
            self.axes[axis] = AxisTwin(lo, hi, p.accel_rad_s2, p.backlash_rad)

    # -- commands (VISCA frame) ------------------------------------------------------------
    def drive(self, pan_code: int, tilt_code: int, pan_dir: int, tilt_dir: int) -> None:
        """Pan-tiltDrive: dir 1 = left/up (negative pan, positive tilt), 2 = right/down, 3 = stop."""
        commands = (("pan", pan_code, pan_dir, 2), ("tilt", tilt_code, tilt_dir, 1))
        for axis, code, direction, positive in commands:
            ax = self.axes[axis]
            if direction == 3:
                ax.mode, ax.drive_rad_s = "drive", 0.0
            else:
                speed = self.profile.code_speed_rad_s(axis, code)
                ax.mode, ax.drive_rad_s = "drive", speed if direction == positive else -speed

    def move_to(self, pan_rad: float, tilt_rad: float, pan_code: int, tilt_code: int) -> None:
        """AbsolutePosition (targets clamped to the mechanical range and the pan-tilt limits)."""
        for axis, target, code in (("pan", pan_rad, pan_code), ("tilt", tilt_rad, tilt_code)):
            ax = self.axes[axis]
            ax.mode = "position"
            lo, hi = ax.bounds()
            ax.target_rad = min(max(target, lo), hi)
            ax.max_rad_s = self.profile.code_speed_rad_s(axis, code)

    def set_limit(self, up_right: bool, pan_rad: float | None, tilt_rad: float | None) -> bool:
        """Pan-tiltLimitSet (a position) or LimitClear (None) of one corner: UpRight sets the
        upper pan and tilt limits, DownLeft the lower ones. DataError when a limit lies outside
        the mechanical range; False (nothing set) when it would leave no range with the other
        corner's."""
        for axis, value in (("pan", pan_rad), ("tilt", tilt_rad)):
            ax = self.axes[axis]
            if value is None:
                continue
            if not ax.lo_rad <= value <= ax.hi_rad:
                raise DataError(f"{axis} limit {value:.4f} rad is outside the range "
                                f"[{ax.lo_rad:.4f}, {ax.hi_rad:.4f}]")
            other = ax.limit_lo_rad if up_right else ax.limit_hi_rad
            if other is not None and (value <= other if up_right else value >= other):
                return False
        for axis, value in (("pan", pan_rad), ("tilt", tilt_rad)):
            if up_right:
                self.axes[axis].limit_hi_rad = value
            else:
                self.axes[axis].limit_lo_rad = value
        return True

    def stop(self) -> None:
        """Stop both axes (decelerating)."""
        for ax in self.axes.values():
            ax.mode, ax.drive_rad_s = "drive", 0.0

    def moving(self) -> bool:
        """True while an axis has speed or a position move to finish."""
        return any(ax.mode == "position" or abs(ax.speed_rad_s) > 0 for ax in self.axes.values())

    def zoom_to(self, counts: float) -> None:
        """CAM_Zoom Direct (clamped to 0..zoom_max)."""
        self.zoom_target = min(max(counts, 0.0), float(self.profile.zoom_max))
        self.zoom_rate = 0.0

    def zoom_drive(self, p: int, tele: bool) -> None:
        """CAM_Zoom variable: speed p (0..7) of the fastest rate, toward tele or wide."""
        self.zoom_target = None
        self.zoom_rate = (p + 1) / 8.0 * self.profile.zoom_counts_s * (1 if tele else -1)

    def zoom_stop(self) -> None:
        """CAM_Zoom Stop."""
        self.zoom_target, self.zoom_rate = None, 0.0

    def store_preset(self, number: int) -> None:
        """CAM_Memory Set: remember where the head points and the zoom."""
        self.presets[number] = (self.axes["pan"].motor_rad, self.axes["tilt"].motor_rad, self.zoom)

    # -- readings ----------------------------------------------------------------------------
    def position_counts(self) -> tuple[int, int]:
        """What Pan-tiltPosInq answers: the motor angles, quantized to counts."""
        q = self.profile.rad_per_count
        return (int(round(self.axes["pan"].motor_rad / q)), int(round(self.axes["tilt"].motor_rad / q)))

    def zoom_counts(self) -> int:
        """What CAM_ZoomPosInq answers."""
        return int(round(self.zoom))

    # -- time ---------------------------------------------------------------------------------
    def step(self, dt_s: float) -> tuple[bool, bool]:
        """Advance ``dt_s``: (pan-tilt move arrived, zoom move arrived) during this step."""
        arrival = ARRIVAL_COUNTS * self.profile.rad_per_count
        was_moving = any(ax.mode == "position" for ax in self.axes.values())
        for ax in self.axes.values():
            ax.step(dt_s, arrival)
        pt_done = was_moving and all(ax.mode != "position" for ax in self.axes.values())
        zoom_done = False
        if self.zoom_target is not None:
            top = self.profile.zoom_counts_s * dt_s
            e = self.zoom_target - self.zoom
            self.zoom += min(max(e, -top), top)
            if abs(self.zoom_target - self.zoom) < 0.5:
                self.zoom, self.zoom_target, zoom_done = self.zoom_target, None, True
        elif self.zoom_rate:
            self.zoom = min(max(self.zoom + self.zoom_rate * dt_s, 0.0), float(self.profile.zoom_max))
        return pt_done, zoom_done
