"""Limits the board enforces (``L``/``B``, docs/serial-protocol.md) and the friction sweep's
stall-capped positioning move: whatever the host does — freezes for 0.1 s, 1 s or for good
in the middle of a move — the pan never passes its soft limit line. With the board's limits,
even a host that drives the full 10 V at the limit and then freezes; with a board that does
not know them (ERR 3: "limits enforced by the host only"), the sweep's own capped move. The
deepest point is the twin's load angle, tracked at every 1 ms sample of the board."""

import math
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tracker.drivers import motor_protocol as mp
from tracker.drivers.motor_board import MotorBoard, limit_output
from tracker.drivers.motor_emulator import MotorEmulator
from tracker.drivers.serial_motor import BOARD_INSET_RAD, BOARD_LIMITS, HOST_LIMITS, SerialMotorDriver
from tracker.drivers.spec import parse_driver_url
from tracker.workbench.experiments.friction_id import friction_sweep

LINES = (math.radians(-89.8), math.radians(89.8))  # the service's guard lines
RATE_HZ = 250


class OldBoard(MotorBoard):
    """A protocol-1 board from before the limit commands: ERR 3 to ``L`` and ``B``."""

    def _act(self, line: mp.Line, now: float) -> bytes:
        if line.verb in ("L", "B"):
            raise mp.FramingError(mp.ERR_UNKNOWN_VERB, f"unknown verb {line.verb}", line.seq)
        return super()._act(line, now)


class Rig:
    """The emulator (a board, old or new) and a driver on it; ``deepest`` the pan's lowest load
    angle seen at any board sample."""

    def __init__(self, tmp_path: Path, old_board: bool = False, watchdog_ms: int = 1000) -> None:
        self.emu = MotorEmulator(OldBoard() if old_board else None, pty_link=tmp_path / "ttyRIG")
        twin = self.emu.board.twin
        self.deepest = self.deepest_motor = 0.0
        step = twin.step

        def tracked(volts: dict[str, float]) -> None:
            step(volts)
            self.deepest = min(self.deepest, twin.load_rad("pan"))
            self.deepest_motor = min(self.deepest_motor, twin.motor_rad("pan"))

        twin.step = tracked  # type: ignore[method-assign,assignment]
        self.emu.start()
        url = f"serial://{self.emu.path}?baud=1000000&rate={RATE_HZ}&watchdog_ms={watchdog_ms}"
        self.d = SerialMotorDriver(parse_driver_url(url), limits_rad={"pan": LINES, "tilt": (-0.78, 0.78)})
        self.d.start()
        self.d.wait_ready(5.0)

    def close(self) -> None:
        self.d.hand_back()
        self.d.close()
        self.emu.close()


@pytest.fixture
def rig(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[Rig]:
    r = Rig(tmp_path, old_board=getattr(request, "param", False))
    yield r
    r.close()


def freeze(seconds: float) -> None:
    """The host's thread stops for ``seconds`` (inf: for good — here 2 s, then no more ticks)."""
    time.sleep(2.0 if math.isinf(seconds) else seconds)


def test_the_board_limit_logic_brakes_before_and_refuses_beyond() -> None:
    hi, lo, brake, vmax = 10_000, -10_000, 700_000, 10_000
    # 54 counts a tick (10 rad/s on the seed's pan): zone 54000²/1.4e6 + 54 = 2136 counts.
    assert limit_output(10_000, hi - 2200, 54, lo, hi, brake, vmax) == 10_000
    assert limit_output(10_000, hi - 2100, 54, lo, hi, brake, vmax) == -vmax
    assert limit_output(-3_000, lo + 2100, -54, lo, hi, brake, vmax) == vmax
    assert limit_output(5_000, hi, 0, lo, hi, brake, vmax) == 0  # at the limit: no further out
    assert limit_output(-5_000, hi + 3, 0, lo, hi, brake, vmax) == -5_000  # back inside is allowed
    assert limit_output(0, hi - 10, 3, lo, hi, 0, vmax) == 0  # no zone without a deceleration
    assert limit_output(7_000, hi - 10, 3, lo, hi, 0, vmax) == 7_000


def test_the_driver_programs_the_board_rounded_inward_and_again_when_the_limits_change(rig: Rig) -> None:
    d, board = rig.d, rig.emu.board
    assert d.board_limits == BOARD_LIMITS and d.describe()["board_limits"] == BOARD_LIMITS
    per = 1.0 / board._counts_per_rad  # rad per count; the counts started at 0 here
    lims = board.limits_counts
    assert lims is not None
    lo, hi = lims["pan"]
    inset = LINES[0] + BOARD_INSET_RAD, LINES[1] - BOARD_INSET_RAD  # then rounded inward
    assert lo * per >= inset[0] > (lo - 1) * per and hi * per <= inset[1] < (hi + 1) * per
    assert board.brake_cps2["pan"] > 0 and board.brake_cps2["tilt"] > board.brake_cps2["pan"]  # J smaller
    d.set_limits("pan", -0.5, 0.25)
    d.tick()
    lims = board.limits_counts
    assert lims is not None and lims["pan"][1] * per == pytest.approx(0.25 - BOARD_INSET_RAD, abs=per)
    assert lims["pan"][1] * per <= 0.25 - BOARD_INSET_RAD and lims["pan"][0] * per >= -0.5 + BOARD_INSET_RAD
    with pytest.raises(Exception, match="limits"):
        d.set_limits("pan", 0.3, 0.2)


@pytest.mark.parametrize("rig", [True], indirect=True)
def test_a_board_that_refuses_the_limit_command_leaves_them_to_the_host_and_says_so(rig: Rig) -> None:
    d = rig.d
    assert d.board_limits == HOST_LIMITS and d.describe()["board_limits"] == HOST_LIMITS
    assert not d.faults()  # an old board is no fault: the rig works, the host enforces the limits
    d.enable()
    for _ in range(20):
        d.command("pan", 1.0)
        d.tick()
    assert rig.emu.board.command_mv["pan"] == 1000 and not d.faults()


def test_a_reconnection_programs_the_limits_again(rig: Rig, tmp_path: Path) -> None:
    d, twin = rig.d, rig.emu.board.twin
    rig.emu.close()  # the board resets: it forgets its limits
    for _ in range(30):
        d.tick()
    restarted = MotorEmulator(MotorBoard(twin), pty_link=rig.emu.pty_link)
    assert restarted.board.limits_counts is None
    restarted.start()
    try:
        end = time.monotonic() + 15.0
        while not (d.state == "connected" and d.describe()["connects"] >= 2):
            assert time.monotonic() < end, "no reconnection"
            time.sleep(0.02)
        assert restarted.board.limits_counts is not None and d.board_limits == BOARD_LIMITS
        assert restarted.board.brake_cps2["pan"] > 0
    finally:
        rig.emu = restarted  # closed by the fixture


@pytest.mark.parametrize("stall_s", [0.1, 1.0, math.inf])
def test_a_host_that_drives_10_v_at_the_limit_and_freezes_is_stopped_by_the_board(
        rig: Rig, stall_s: float) -> None:
    """No capped move here: the host itself drives the full 10 V towards -90° and freezes at
    -40° (about 9 rad/s). The board brakes on its own in its zone and holds the line."""
    d = rig.d
    d.enable()
    frozen = False
    for _ in range(int(2.0 * RATE_HZ)):
        d.command("pan", -10.0)
        if not frozen and d.read_encoder("pan") < math.radians(-40.0):
            frozen = True
            freeze(stall_s)
            if math.isinf(stall_s):
                break
        d.tick()
    rig.emu.board.catch_up()
    assert frozen
    assert rig.deepest > LINES[0], (math.degrees(rig.deepest), math.degrees(rig.deepest_motor))
    assert rig.emu.board.limit_brakes["pan"] > 0
    assert not any("over-travel" in f for f in d.faults()), d.faults()


@pytest.mark.parametrize("rig", [False, True], indirect=True, ids=["board-limits", "host-only"])
@pytest.mark.parametrize("stall_s", [0.1, 1.0, math.inf])
def test_a_host_that_freezes_during_the_sweeps_first_move_never_passes_the_soft_limit(
        rig: Rig, stall_s: float) -> None:
    """The live sweep on pan; the host freezes once the pan has passed -30° on its first move
    (to -65°, its fastest stretch). A 0.1 s freeze is no fault and the sweep goes on. On a board
    that enforces no limits, a longer one trips its watchdog (200 ms while the sweep has the
    axis) and the axis coasts to rest before the line: the capped move alone. A board that
    enforces them keeps the URL's 1 s watchdog and brakes before its line."""
    d = rig.d
    d.enable()
    for _ in range(10):
        d.tick()
    sweep = friction_sweep("pan", d.sample_period_s, (d.read_encoder("pan"), d.sample_time_s),
                           travel_rad=0.85 * LINES[1], voltages_per_direction=4, limits_rad=LINES)
    done = d.take_over("a test", "pan", sweep)
    old = rig.d.board_limits == HOST_LIMITS
    assert rig.emu.board.watchdog_ms == 1000  # set at the next exchange
    frozen, gap = False, 0.0
    for _ in range(int(2.5 * RATE_HZ)):
        if not frozen and d.read_encoder("pan") < math.radians(-30.0):
            assert rig.emu.board.watchdog_ms == (200 if old else 1000)
            frozen = True
            t0 = time.perf_counter()
            freeze(stall_s)
            if math.isinf(stall_s):
                break
            d.tick()
            gap = time.perf_counter() - t0
        d.tick()
    rig.emu.board.catch_up()
    assert frozen
    assert rig.deepest > LINES[0], math.degrees(rig.deepest)
    if stall_s < 0.2 and gap < 0.18:  # a loaded machine may hold the thread longer than asked
        assert not d.faults(), d.faults()
        assert not done.done()  # the sweep goes on
    elif old:
        assert any("watchdog" in f and "200 ms" in f for f in d.faults()), d.faults()
    d.hand_back()
    d.clear_faults()
    d.tick()
    assert rig.emu.board.watchdog_ms == 1000  # the URL's watchdog is back with the hand-back


def test_the_board_answers_the_limit_lines_and_refuses_bad_ones() -> None:
    board = MotorBoard()

    def ask(verb: str, *args: object) -> tuple[str, tuple[str, ...]]:
        line = mp.parse_line(board.handle(mp.frame(9, verb, *args)), mp.MAX_REPLY)
        return line.verb, line.args

    assert ask("L", -100, 100, -50, 50)[0] == "OK" and board.limits_counts == {"pan": (-100, 100),
                                                                                 "tilt": (-50, 50)}
    assert ask("L", -100, 100, -50) == ("ERR", ("4", "L", "needs", "4", "counts", "(or", "none)"))
    assert ask("L", 100, -100, -50, 50)[1][0] == "5"  # lo >= hi
    assert ask("L", -(2**31) - 1, 100, -50, 50)[1][0] == "5"  # beyond 32 bits
    assert board.limits_counts == {"pan": (-100, 100), "tilt": (-50, 50)}  # a refused line changes nothing
    assert ask("B", 5, -1)[1][0] == "5" and ask("B", 5)[1][0] == "4"
    assert ask("B", 700_000, 1_300_000)[0] == "OK" and board.brake_cps2 == {"pan": 700_000, "tilt": 1_300_000}
    longest = mp.frame(255, "L", -(2**31), -(2**31) + 1, -(2**31), -(2**31) + 1)
    assert len(longest) <= mp.MAX_LINE
    assert ask("L")[0] == "OK" and board.limits_counts is None  # off
