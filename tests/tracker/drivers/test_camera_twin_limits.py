"""The camera's own pan-tilt limits, without sockets: the VISCA bytes, the responder's answers and
the twin's head, which never passes a limit set while it could still stop."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tracker.drivers import visca_protocol as vp
from tracker.drivers.camera_profiles import get_profile, profile_names
from tracker.drivers.camera_responder import CameraResponder
from tracker.drivers.camera_servo import dead_band_rad, handoff_room_rad, limit_speed_rad_s
from tracker.drivers.camera_twin import CameraTwin
from tracker.errors import DataError

DEG = math.radians(1.0)


def test_limit_set_and_clear_bytes_are_the_sony_command_list_s() -> None:
    # Sony SRG-300H / SRG-X400 lists: 8x 01 06 07 00 0W 0Y0Y0Y0Y 0Z0Z0Z0Z FF, W 1 UpRight / 0 DownLeft;
    # LimitClear 8x 01 06 07 01 0W 07 0F 0F 0F 07 0F 0F 0F FF.
    assert vp.pan_tilt_limit_set(vp.LIMIT_UP_RIGHT, 0x0990, 0x0510).hex(" ") == \
        "81 01 06 07 00 01 00 09 09 00 00 05 01 00 ff"
    assert vp.pan_tilt_limit_set(vp.LIMIT_DOWN_LEFT, -2448, -1).hex(" ") == \
        "81 01 06 07 00 00 0f 06 07 00 0f 0f 0f 0f ff"
    assert vp.pan_tilt_limit_clear(vp.LIMIT_UP_RIGHT).hex(" ") == \
        "81 01 06 07 01 01 07 0f 0f 0f 07 0f 0f 0f ff"
    with pytest.raises(DataError, match="corner 2"):
        vp.pan_tilt_limit_set(2, 0, 0)
    with pytest.raises(DataError, match="16-bit"):
        vp.pan_tilt_limit_set(vp.LIMIT_UP_RIGHT, 0x8000, 0)


class Replies:
    def __init__(self) -> None:
        self.got: list[bytes] = []

    def __call__(self, tag: object, reply: bytes) -> None:
        self.got.append(reply)


def answer(responder: CameraResponder, packet: bytes) -> list[bytes]:
    replies = Replies()
    responder.handle(packet, None, replies)
    return replies.got


def test_the_responder_sets_clears_and_refuses_limits_as_a_camera() -> None:
    twin = CameraTwin(get_profile("generic"))
    r = CameraResponder(twin)
    q = twin.profile.rad_per_count
    ok = [vp.ack(1), vp.completion(1)]
    assert answer(r, vp.pan_tilt_limit_set(vp.LIMIT_UP_RIGHT, 1000, 500)) == ok
    assert answer(r, vp.pan_tilt_limit_set(vp.LIMIT_DOWN_LEFT, -900, -200)) == ok
    assert twin.axes["pan"].bounds() == pytest.approx((-900 * q, 1000 * q))
    assert twin.axes["tilt"].bounds() == pytest.approx((-200 * q, 500 * q))
    syntax = [vp.error(0, vp.ERR_SYNTAX)]
    # malformed: a corner 2, a set/clear byte 2, a short packet, clear fields other than 7FFF
    assert answer(r, bytes.fromhex("81 01 06 07 00 02 00 00 00 00 00 00 00 00 ff")) == syntax
    assert answer(r, bytes.fromhex("81 01 06 07 02 01 00 00 00 00 00 00 00 00 ff")) == syntax
    assert answer(r, bytes.fromhex("81 01 06 07 00 01 00 00 00 00 00 00 00 ff")) == syntax
    assert answer(r, bytes.fromhex("81 01 06 07 01 01 07 0f 0f 0e 07 0f 0f 0f ff")) == syntax
    # a position outside the mechanical range (pan 170 deg = 2448 counts): syntax error
    assert answer(r, vp.pan_tilt_limit_set(vp.LIMIT_UP_RIGHT, 2600, 0)) == syntax
    # an upper corner below the lower one leaves no range: not executable, nothing changed
    refused = [vp.error(0, vp.ERR_NOT_EXECUTABLE)]
    assert answer(r, vp.pan_tilt_limit_set(vp.LIMIT_UP_RIGHT, -1000, 500)) == refused
    assert twin.axes["pan"].bounds() == pytest.approx((-900 * q, 1000 * q))
    assert answer(r, vp.pan_tilt_limit_clear(vp.LIMIT_UP_RIGHT)) == ok
    assert twin.axes["pan"].bounds() == (-900 * q, twin.axes["pan"].hi_rad)
    off = CameraResponder(CameraTwin(get_profile("generic")), limit_commands=False)
    assert answer(off, vp.pan_tilt_limit_set(vp.LIMIT_UP_RIGHT, 1000, 500)) == syntax


def run(twin: CameraTwin, seconds: float, dt_s: float = 0.005) -> tuple[float, float]:
    """Step the twin; the (lowest, highest) pan motor angle seen."""
    lo = hi = twin.axes["pan"].motor_rad
    for _ in range(int(seconds / dt_s)):
        twin.step(dt_s)
        lo, hi = min(lo, twin.axes["pan"].motor_rad), max(hi, twin.axes["pan"].motor_rad)
    return lo, hi


@pytest.mark.parametrize("name", profile_names())
def test_a_full_speed_drive_and_a_move_past_a_limit_stop_on_it(name: str) -> None:
    twin = CameraTwin(get_profile(name))
    limit = 60 * DEG
    assert twin.set_limit(True, limit, 30 * DEG)
    twin.drive(vp.PAN_SPEED_MAX, 1, vp.PAN_RIGHT, vp.TILT_STOP)
    _, top = run(twin, 4.0)
    assert top <= limit and twin.axes["pan"].motor_rad == limit and twin.axes["pan"].speed_rad_s == 0.0
    twin.drive(3, 1, vp.PAN_LEFT, vp.TILT_STOP)  # away from the limit: free
    run(twin, 0.5)
    assert twin.axes["pan"].motor_rad < limit - 0.5 * DEG
    twin.move_to(100 * DEG, 0.0, vp.PAN_SPEED_MAX, vp.TILT_SPEED_MAX)
    _, top = run(twin, 4.0)
    assert top <= limit and twin.axes["pan"].motor_rad == limit


def test_a_limit_set_just_ahead_of_a_fast_head_is_passed_then_kept() -> None:
    """The camera brakes at its own acceleration: a limit set closer than its stopping distance
    is passed (the emulator does not stop the head dead), and the head comes back to it."""
    twin = CameraTwin(get_profile("generic"))
    twin.drive(vp.PAN_SPEED_MAX, 1, vp.PAN_RIGHT, vp.TILT_STOP)
    run(twin, 1.0)  # 100 deg/s after 0.5 s
    at = twin.axes["pan"].motor_rad
    assert twin.set_limit(True, at + 2 * DEG, 80 * DEG)
    _, top = run(twin, 2.0)
    stopping = (100 * DEG) ** 2 / (2 * twin.profile.accel_rad_s2)
    assert top == pytest.approx(at + stopping, abs=1 * DEG)  # past the limit by about 23 deg
    twin.drive(1, 1, vp.PAN_RIGHT, vp.TILT_STOP)  # outward again: refused
    _, top2 = run(twin, 1.0)
    assert top2 <= top


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(profile_names()),
    start_deg=st.floats(-80.0, 80.0),
    limit_deg=st.floats(-85.0, 85.0),
    commands=st.lists(st.tuples(st.integers(1, vp.PAN_SPEED_MAX),
                                st.sampled_from((vp.PAN_LEFT, vp.PAN_RIGHT)), st.floats(0.0, 1.5)),
                      min_size=1, max_size=6),
)
def test_the_head_never_passes_limits_set_before_the_drive(
    name: str, start_deg: float, limit_deg: float, commands: list[tuple[int, int, float]]
) -> None:
    """Whatever drives follow each other and however long each lasts (a host stalled or gone),
    a head inside its limits stays inside them."""
    twin = CameraTwin(get_profile(name))
    lo, hi = sorted((start_deg * DEG, limit_deg * DEG))
    if hi - lo < 0.1 * DEG:
        hi = lo + 0.1 * DEG
    twin.axes["pan"].motor_rad = twin.axes["pan"].load_rad = min(start_deg * DEG, hi)
    assert twin.set_limit(True, hi, None) and twin.set_limit(False, lo, None)
    for code, direction, seconds in commands:
        twin.drive(code, 1, direction, vp.TILT_STOP)
        low, top = run(twin, seconds)
        assert lo - 1e-12 <= low and top <= hi + 1e-12


@pytest.mark.parametrize("name", profile_names())
def test_the_hand_off_comes_before_the_speed_law_brakes_and_leaves_two_late_periods(name: str) -> None:
    """Within handoff_room_rad the driver hands the drive to the camera; outside it, a drive at
    the law's speed stalled for two more periods (beyond the law's one) still stops in time."""
    prof = get_profile(name)
    period, latency = 0.04, 0.03
    for axis in ("pan", "tilt"):
        for v in (prof.code_speed_rad_s(axis, c) for c in range(1, len(prof.speeds_rad_s[axis]) + 1)):
            reach = handoff_room_rad(prof, axis, v, period_s=period, latency_s=latency)
            brake = 0.5 * prof.accel_rad_s2
            # the law at room = reach still allows v (it has not started braking)
            dead = dead_band_rad(prof, axis, period)
            assert limit_speed_rad_s(reach - 0.5 * dead, brake, latency + 2 * period) >= v * (1 - 1e-9)
            travel = v * (latency + 3 * period) + v * v / (2 * brake)
            assert travel < reach
