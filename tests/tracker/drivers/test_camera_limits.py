"""The camera never passes its soft limits, whatever the host does: the real VISCA driver (its
command cycle on a loop thread of its own, as in the service) against the camera emulator
over UDP on 127.0.0.1, with the driver's thread frozen mid-drive (a stalled host) for good.

Bug: a camera in speed drive keeps moving until told otherwise, and the host-side law left
room for one late command period only; a host that stalled longer, or died, drove the head
past the limit (to the mechanical range when it never came back: 80 deg past a 90 deg limit).
"""

from __future__ import annotations

import asyncio
import math
import threading
import time
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager

import pytest

from tracker.drivers.camera_emulator import CameraEmulator
from tracker.drivers.camera_profiles import CameraProfile, get_profile, profile_names
from tracker.drivers.camera_twin import CameraTwin
from tracker.drivers.spec import parse_driver_url
from tracker.drivers.visca import ViscaCamera

DEG = math.radians(1.0)
LIMITS = {"pan": (-90 * DEG, 90 * DEG), "tilt": (-15 * DEG, 45 * DEG)}
RATE_HZ = 25.0
AXES = ("pan", "tilt")


async def until(cond: Callable[[], object], timeout_s: float = 5.0, what: str = "condition") -> None:
    end = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > end:
            pytest.fail(f"{what} not reached within {timeout_s} s")
        await asyncio.sleep(0.005)


class WatchedTwin(CameraTwin):
    """The emulator's twin, recording after every step how far each axis went past the soft
    limits (console frame, rad; negative while inside) and calling ``watch``."""

    def __init__(self, profile: CameraProfile) -> None:
        super().__init__(profile)
        self.past = {a: -math.inf for a in AXES}
        self.watch: Callable[[], None] | None = None

    def console(self, axis: str) -> float:
        return self.profile.sign[axis] * self.axes[axis].motor_rad

    def step(self, dt_s: float) -> tuple[bool, bool]:
        out = super().step(dt_s)
        for axis in AXES:
            lo, hi = LIMITS[axis]
            x = self.console(axis)
            self.past[axis] = max(self.past[axis], x - hi, lo - x)
        if self.watch is not None:
            self.watch()
        return out


@asynccontextmanager
async def rig(profile: str = "generic", *, limit_commands: bool = True, latency_s: float = 0.02,
              start: dict[str, float] | None = None, **options: object,
              ) -> AsyncIterator[tuple[ViscaCamera, CameraEmulator, WatchedTwin]]:
    twin = WatchedTwin(get_profile(profile))
    for axis, x in (start or {}).items():
        twin.axes[axis].motor_rad = twin.axes[axis].load_rad = twin.profile.sign[axis] * x
    emu = CameraEmulator(profile, latency_s=latency_s, seed=5, twin=twin, limit_commands=limit_commands)
    port = await emu.start()
    cam = ViscaCamera(parse_driver_url(f"visca+udp://127.0.0.1:{port}"), get_profile(profile), LIMITS,
                      rate_hz=RATE_HZ, own_thread=True, **options)  # type: ignore[arg-type]
    try:
        cam.start()
        await until(lambda: cam.ready, 5.0, "connection")
        cam.enable()
        yield cam, emu, twin
    finally:
        await cam.close()
        await emu.close()


def freeze(cam: ViscaCamera, release: threading.Event, seconds: float) -> None:
    """Block the driver's own event loop (its thread) for ``seconds`` or until ``release``."""
    lt = cam._loop_thread
    assert lt is not None
    lt.loop.call_soon_threadsafe(release.wait, seconds)


def run_up(profile: CameraProfile, axis: str, side: int, trigger_rad: float) -> float:
    """A start far enough from the ``side`` limit to reach full (or the law's) speed first."""
    lo, hi = LIMITS[axis]
    v = profile.max_speed_rad_s(axis)
    x = (hi if side > 0 else lo) - side * (trigger_rad + v * v / (2 * profile.accel_rad_s2) + 3 * DEG)
    return min(max(x, lo + 1 * DEG), hi - 1 * DEG)


def kill(cam: ViscaCamera) -> None:
    """Cancel the driver's command cycle where it runs, sending nothing (a host process gone)."""
    lt, task = cam._loop_thread, cam._task
    assert lt is not None and task is not None
    lt.loop.call_soon_threadsafe(task.cancel)


STALLS: list[int | str | None] = [2, 5, 50, None, "killed"]  # command periods; None: frozen for good


@pytest.mark.parametrize("stall", STALLS, ids=lambda s: "forever" if s is None else str(s) + (
    "" if s == "killed" else "-periods"))
@pytest.mark.parametrize("side", [1, -1], ids=["up-right", "down-left"])
@pytest.mark.parametrize("name", profile_names())
async def test_a_host_stalled_mid_drive_never_lets_the_head_pass_a_soft_limit(
    name: str, side: int, stall: int | str | None
) -> None:
    """Both axes at full speed toward one corner; 2 deg before the first soft limit the driver's
    thread freezes for N periods (or for good), or its command cycle is cancelled. The head must
    stop at or inside every limit."""
    prof = get_profile(name)
    trigger = 2 * DEG
    start = {a: run_up(prof, a, side, trigger) for a in AXES}
    async with rig(name, start=start, link_lost_s=5.0) as (cam, _emu, twin):
        await until(lambda: all(abs(cam.read_encoder(a) - start[a]) < 0.2 * DEG for a in AXES), 3.0, "start")
        assert cam.describe()["camera_limits"]["state"] == "set"
        release = threading.Event()
        frozen: list[float] = []

        def watch() -> None:
            if not frozen and max(twin.past.values()) >= -trigger:
                frozen.append(time.monotonic())
                if stall == "killed":
                    kill(cam)
                else:
                    freeze(cam, release, 3600.0 if not isinstance(stall, int) else stall / RATE_HZ)

        twin.watch = watch
        for axis in AXES:
            cam.set_rate(axis, side * prof.max_speed_rad_s(axis))
        try:
            await until(lambda: frozen, 20.0, "the trigger")
            if isinstance(stall, int):
                await asyncio.sleep(stall / RATE_HZ)
            await until(lambda: not twin.moving(), 20.0, "the head at rest")
            await asyncio.sleep(0.2)
            assert not twin.moving()
        finally:
            twin.watch = None
            release.set()
        for axis in AXES:
            assert twin.past[axis] <= 1e-12, (axis, twin.past[axis] / DEG)


@pytest.mark.parametrize("steer", ["rate", "target"])
async def test_a_camera_refusing_limit_set_is_shown_and_the_hand_off_still_stops_the_head(steer: str) -> None:
    """A camera without Pan-tiltLimitSet answers a syntax error: the status says so (the host is
    the only guard). The last stretch toward the limit is still an absolute move to the limit
    (a rate drive) or to the target, so a host that dies once it was sent leaves the head
    stopped there, not past the limit."""
    prof = get_profile("generic")
    start = {"pan": run_up(prof, "pan", 1, 0.0), "tilt": 0.0}
    async with rig(limit_commands=False, start=start, link_lost_s=5.0) as (cam, _emu, twin):
        limits = cam.describe()["camera_limits"]
        assert limits["state"] == "refused" and limits["guard"] == "host only"
        assert "syntax error" in limits["error"]
        await until(lambda: abs(cam.read_encoder("pan") - start["pan"]) < 0.2 * DEG, 3.0, "start")
        release = threading.Event()
        frozen: list[float] = []

        def watch() -> None:  # the moment the camera's position loop has the pan axis
            if not frozen and twin.axes["pan"].mode == "position":
                frozen.append(time.monotonic())
                freeze(cam, release, 3600.0)

        twin.watch = watch
        end = LIMITS["pan"][1] - (0.0 if steer == "rate" else 0.5 * DEG)
        if steer == "rate":
            cam.set_rate("pan", prof.max_speed_rad_s("pan"))
        else:
            cam.set_target("pan", end)
        try:
            await until(lambda: frozen, 10.0, "the hand-off to the camera's position loop")
            await until(lambda: not twin.moving(), 10.0, "the head at rest")
        finally:
            twin.watch = None
            release.set()
        assert twin.past["pan"] <= 1e-12
        assert twin.console("pan") == pytest.approx(end, abs=0.1 * DEG)  # all the way there


def camera_bounds_deg(twin: CameraTwin, axis: str) -> tuple[float, float]:
    """The twin's own limits in the console's frame (deg)."""
    lo, hi = (twin.profile.sign[axis] * v for v in twin.axes[axis].bounds())
    return math.degrees(min(lo, hi)), math.degrees(max(lo, hi))


def assert_programmed(twin: CameraTwin, limits: dict[str, tuple[float, float]]) -> None:
    """The camera's limits lie inside the soft limits by less than one count."""
    count_deg = math.degrees(twin.profile.rad_per_count)
    for axis, (lo, hi) in limits.items():
        got_lo, got_hi = camera_bounds_deg(twin, axis)
        assert math.degrees(lo) <= got_lo < math.degrees(lo) + count_deg, axis
        assert math.degrees(hi) - count_deg < got_hi <= math.degrees(hi), axis


async def test_limits_are_programmed_on_connect_and_again_after_a_reconnection() -> None:
    async with rig(link_lost_s=0.3) as (cam, emu, twin):
        assert_programmed(twin, LIMITS)
        status = cam.describe()["camera_limits"]
        assert status["state"] == "set" and status["guard"] == "camera and host"
        assert -90.0 <= status["pan_deg"][0] < -89.9 and 44.9 < status["tilt_deg"][1] <= 45.0
        # the camera loses its limits (a power cycle) and the link drops in the middle of a slow
        # speed drive: the reconnection sets them again and stops the drive (bug: the stop the
        # disable queued died with the link, and the head ran on to the mechanical range)
        twin.set_limit(True, None, None)
        twin.set_limit(False, None, None)
        cam.set_rate("pan", math.radians(3.0))
        await until(lambda: twin.axes["pan"].speed_rad_s != 0.0, 2.0, "drive")
        emu.drop = lambda direction, seq, payload: True
        await until(lambda: cam.faults(), 3.0, "link lost")
        assert twin.axes["pan"].speed_rad_s != 0.0  # still driving: nothing reached the camera
        emu.drop = None
        await until(lambda: cam.connects >= 2 and cam.ready, 10.0, "reconnection")
        assert_programmed(twin, LIMITS)
        assert cam.describe()["camera_limits"]["state"] == "set"
        await until(lambda: twin.axes["pan"].speed_rad_s == 0.0, 1.0, "the drive stopped")


async def test_changing_the_soft_limits_programs_the_camera_again() -> None:
    async with rig() as (cam, _emu, twin):
        narrow = {"pan": (-30 * DEG, 40 * DEG), "tilt": (-10 * DEG, 20 * DEG)}
        cam.set_limits(narrow)
        await until(lambda: camera_bounds_deg(twin, "pan")[1] < 41.0, 3.0, "new limits")
        await until(lambda: cam.describe()["camera_limits"]["state"] == "set", 3.0, "set")
        assert_programmed(twin, narrow)
        # limits that cross the old ones (the new upper corner below the old lower one) go
        # through LimitClear first; the camera ends with the new ones
        crossed = {"pan": (-80 * DEG, -50 * DEG), "tilt": (25 * DEG, 40 * DEG)}
        cam.set_limits(crossed)
        await until(lambda: camera_bounds_deg(twin, "pan")[1] < -49.0, 3.0, "crossed limits")
        await until(lambda: cam.describe()["camera_limits"]["state"] == "set", 3.0, "set")
        assert_programmed(twin, crossed)
        assert cam.limits("pan") == crossed["pan"]


async def test_a_driver_without_soft_limits_leaves_the_camera_s_own_alone() -> None:
    """Limits an installer set on the camera are not widened by a driver given none (the
    command-line speed-id job); set_limits then programs them."""
    emu = CameraEmulator("generic", seed=5)
    port = await emu.start()
    q = emu.profile.rad_per_count
    emu.twin.set_limit(True, 500 * q, 200 * q)
    cam = ViscaCamera(parse_driver_url(f"visca+udp://127.0.0.1:{port}"), get_profile("generic"))
    try:
        cam.start()
        await until(lambda: cam.ready, 5.0, "connection")
        assert cam.describe()["camera_limits"] == {"state": "not programmed", "guard": "host only",
                                                   "error": None}
        assert emu.twin.axes["pan"].bounds()[1] == 500 * q
        cam.set_limits(LIMITS)
        await until(lambda: cam.describe()["camera_limits"]["state"] == "set", 3.0, "set")
        assert_programmed(emu.twin, LIMITS)
    finally:
        await cam.close()
        await emu.close()
