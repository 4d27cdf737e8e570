"""The serial motor driver against the motor controller emulator, through a real pseudo-terminal:
connect, command and read, the board's watchdog, error replies, a quiet board, a restarted
board, the soft limits, the engine and the friction-ID sweep on it."""

import asyncio
import math
import os
import select
import subprocess
import sys
import time
import tty
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tracker.drivers import motor_protocol as mp
from tracker.drivers.motor_board import SEED_COUNTS_PER_REV, SEED_GEAR_RATIO, MotorBoard
from tracker.drivers.motor_emulator import MotorEmulator
from tracker.drivers.serial_motor import SerialMotorDriver
from tracker.drivers.spec import parse_driver_url
from tracker.errors import DriverFault

RATE_HZ = 250  # gentle on a shared machine; 1 kHz works the same (bench/bench_loop_under_load.py)
COUNT_RAD = 2 * math.pi / (SEED_COUNTS_PER_REV * SEED_GEAR_RATIO)
ROOT = Path(__file__).resolve().parents[3]


def until(cond: Callable[[], object], timeout_s: float, what: str) -> None:
    end = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > end:
            pytest.fail(f"{what}: not within {timeout_s} s")
        time.sleep(0.01)


def new_driver(path: str, **kw: object) -> SerialMotorDriver:
    d = SerialMotorDriver(parse_driver_url(f"serial://{path}?baud=1000000&rate={RATE_HZ}"), **kw)  # type: ignore[arg-type]
    d.start()
    d.wait_ready(5.0)
    return d


def drive(d: SerialMotorDriver, pan_v: float, tilt_v: float, seconds: float) -> None:
    for _ in range(int(round(seconds * RATE_HZ))):
        d.command("pan", pan_v)
        d.command("tilt", tilt_v)
        d.tick()


@pytest.fixture
def emulator(tmp_path: Path) -> Iterator[MotorEmulator]:
    emu = MotorEmulator(pty_link=tmp_path / "ttyRIG")
    emu.start()
    yield emu
    emu.close()


@pytest.fixture
def driver(emulator: MotorEmulator) -> Iterator[SerialMotorDriver]:
    d = new_driver(emulator.path)
    yield d
    d.close()


def test_connects_reads_the_hello_and_where_the_axes_stand(emulator: MotorEmulator) -> None:
    emulator.board.set_angle("pan", math.radians(10.0))
    emulator.board.set_angle("tilt", math.radians(-5.0))
    d = new_driver(emulator.path)
    try:
        info = d.describe()
        assert info["state"] == "connected" and info["kind"] == "serial"
        assert info["counts_per_rev"] == [2000, 2000] and "3dat-mc-emu" in info["board"]
        assert d.read_encoder("pan") == pytest.approx(math.radians(10.0), abs=COUNT_RAD)
        assert d.read_encoder("tilt") == pytest.approx(math.radians(-5.0), abs=COUNT_RAD)
        assert not d.enabled and not emulator.board.armed
    finally:
        d.close()


def test_commands_move_the_rig_and_the_angle_is_the_counts(
        driver: SerialMotorDriver, emulator: MotorEmulator) -> None:
    driver.enable()
    drive(driver, 1.2, -1.2, 0.15)
    assert emulator.board.armed and emulator.board.command_mv == {"pan": 1200, "tilt": -1200}
    driver.disable()
    drive(driver, 0.0, 0.0, 0.3)  # disarmed: the axes coast to a stop
    twin = emulator.board.twin
    assert not emulator.board.armed and twin.velocity_rad_s("pan") == 0.0
    assert driver.read_encoder("pan") > 0.05 and driver.read_encoder("tilt") < -0.05
    for axis in ("pan", "tilt"):
        assert driver.read_encoder(axis) == pytest.approx(twin.motor_rad(axis), abs=COUNT_RAD)
    assert driver.describe()["achieved_rate_hz"] > 0.5 * RATE_HZ


def test_the_boards_watchdog_stops_the_motor_when_the_host_stalls(
        driver: SerialMotorDriver, emulator: MotorEmulator) -> None:
    board = emulator.board
    driver.enable()
    drive(driver, 1.2, 0.0, 0.1)
    assert board.armed and board.command_mv["pan"] == 1200
    # The host stalls: no more ticks. The command lapses 100 ms after the last one.
    until(lambda: not board.armed, 3.0, "board disarmed by its watchdog")
    assert board.watchdog_tripped and board.watchdog_trips == 1 and board.command_mv["pan"] == 0

    def stopped() -> bool:
        board.catch_up()
        return board.twin.velocity_rad_s("pan") == 0.0

    until(stopped, 3.0, "motor stopped")
    # The driver's idle read sees it and latches a fault the console shows.
    until(lambda: driver.faults(), 3.0, "watchdog fault")
    assert "watchdog" in driver.faults()[0] and not driver.enabled


def talk(fd: int, raw: bytes) -> mp.Line:
    os.write(fd, raw)
    buf = b""
    end = time.monotonic() + 2.0
    while not buf.endswith(b"\n"):
        assert select.select([fd], [], [], max(0.0, end - time.monotonic()))[0], f"no reply to {raw!r}"
        buf += os.read(fd, 256)
    return mp.parse_line(buf, mp.MAX_REPLY)


@pytest.mark.parametrize(
    ("raw", "seq", "code"),
    [
        pytest.param(b"12 C 100 200*00\n", 12, mp.ERR_CHECKSUM, id="bad-checksum"),
        pytest.param(mp.frame(13, "Q"), 13, mp.ERR_UNKNOWN_VERB, id="unknown-verb"),
        pytest.param(mp.frame(14, "C", 100), 14, mp.ERR_BAD_ARGUMENT, id="missing-argument"),
        pytest.param(mp.frame(15, "C", 20_000, 0), 15, mp.ERR_OUT_OF_RANGE, id="beyond-vmax"),
        pytest.param(mp.frame(16, "C", *(["1"] * 30)), 16, mp.ERR_TOO_LONG, id="too-long"),
        pytest.param(b"hello\n", None, mp.ERR_CHECKSUM, id="not-a-frame"),
    ],
)
def test_malformed_lines_get_error_replies_through_the_pty(
        emulator: MotorEmulator, raw: bytes, seq: int | None, code: int) -> None:
    fd = os.open(emulator.device or "", os.O_RDWR | os.O_NOCTTY)
    try:
        tty.setraw(fd)
        line = talk(fd, raw)
        assert (line.seq, line.verb, line.args[0]) == (seq, "ERR", str(code))
        assert talk(fd, mp.frame(17, "H")).verb == "H"  # and the next good line is answered
    finally:
        os.close(fd)


def test_a_board_that_stops_answering_is_a_fault_then_reconnects_disabled(
        driver: SerialMotorDriver, emulator: MotorEmulator) -> None:
    driver.enable()
    drive(driver, 0.8, 0.0, 0.05)
    emulator.stall(0.6)
    drive(driver, 0.8, 0.0, 0.4)
    assert any("link lost" in f for f in driver.faults()) and not driver.enabled
    assert driver.state in ("reconnecting", "connected")
    until(lambda: driver.state == "connected", 15.0, "reconnected")
    assert not emulator.board.armed and driver.describe()["connects"] == 2
    with pytest.raises(DriverFault, match="fault latched"):
        driver.enable()
    driver.clear_faults()
    driver.enable()
    drive(driver, 0.8, 0.0, 0.05)
    assert emulator.board.armed and emulator.board.command_mv["pan"] == 800


def test_a_restarted_board_is_re_referenced_and_nothing_moves_until_enabled(
        driver: SerialMotorDriver, emulator: MotorEmulator) -> None:
    driver.enable()
    drive(driver, 1.2, 0.0, 0.15)
    driver.disable()
    drive(driver, 0.0, 0.0, 0.3)
    before = driver.read_encoder("pan")
    assert before > 0.05
    twin = emulator.board.twin
    emulator.close()  # the board resets (a USB reconnect does that to an Arduino)
    drive(driver, 0.0, 0.0, 0.1)
    assert any("link lost" in f for f in driver.faults())
    restarted = MotorEmulator(MotorBoard(twin), pty_link=emulator.pty_link)  # the same mount
    restarted.start()
    try:
        assert restarted.board.counts("pan") == 0  # counts start again at power-up
        until(lambda: driver.state == "connected", 15.0, "reconnected to the restarted board")
        assert driver.read_encoder("pan") == pytest.approx(before, abs=2 * COUNT_RAD)
        assert driver.describe()["re_referenced"] == 1
        drive(driver, 1.5, 0.0, 0.2)  # disabled: nothing is sent but reads
        assert not restarted.board.armed and twin.motor_rad("pan") == pytest.approx(before, abs=COUNT_RAD)
        driver.clear_faults()
        driver.enable()
        drive(driver, -1.5, 0.0, 0.2)
        assert driver.read_encoder("pan") < before - 0.01
    finally:
        driver.close()
        restarted.close()


def test_the_driver_will_not_drive_further_past_a_soft_limit(emulator: MotorEmulator) -> None:
    emulator.board.set_angle("pan", 0.31)
    d = new_driver(emulator.path, limits_rad={"pan": (-0.3, 0.3)})
    try:
        d.enable()
        drive(d, 2.0, 0.0, 0.1)
        assert emulator.board.command_mv["pan"] == 0 and d.describe()["refused_at_limits"]["pan"] > 0
        assert emulator.board.twin.motor_rad("pan") == pytest.approx(0.31, abs=COUNT_RAD)
        drive(d, -2.0, 0.0, 0.05)  # back inside is allowed
        assert emulator.board.command_mv["pan"] == -2000
        d.disable()
        drive(d, 0.0, 0.0, 0.05)
        assert d.read_encoder("pan") < 0.31 - 0.002
    finally:
        d.close()


def test_a_non_finite_command_latches_a_fault(driver: SerialMotorDriver) -> None:
    driver.enable()
    driver.command("pan", math.nan)
    assert driver.faults() and not driver.enabled


async def test_the_engine_steers_the_serial_rig_and_a_lost_port_is_a_fault(
        driver: SerialMotorDriver, emulator: MotorEmulator) -> None:
    from tracker.engine import Engine

    engine = Engine(driver)
    task = asyncio.create_task(engine.run(realtime=True))
    twin = emulator.board.twin

    async def until_async(cond: Callable[[], bool], timeout_s: float, what: str) -> None:
        end = time.monotonic() + timeout_s
        while not cond():
            if task.done():
                task.result()  # the loop's error, if any
            if time.monotonic() > end or task.done():
                pytest.fail(f"{what}: not within {timeout_s} s ({engine.mode}, {driver.describe()})")
            await asyncio.sleep(0.01)

    try:
        await until_async(lambda: driver.enabled, 15.0, "enabled once ready")
        engine.point(0.3, -0.1)
        await until_async(lambda: abs(twin.load_rad("pan") - 0.3) < 0.005
                          and abs(twin.load_rad("tilt") + 0.1) < 0.005, 15.0, "pointed")
        assert engine.mode == "manual" and engine.timing().ticks > 0
        emulator.close()
        await until_async(lambda: engine.mode == "fault", 10.0, "fault mode")
    finally:
        engine.stop()
        await task


def test_sample_times_are_the_boards_clock_unwrapped(
    driver: SerialMotorDriver, emulator: MotorEmulator
) -> None:
    drive(driver, 0.0, 0.0, 0.02)
    t0, b0 = driver.sample_time_s, emulator.board.now_s()
    drive(driver, 0.0, 0.0, 0.4)
    elapsed_board = emulator.board.now_s() - b0
    assert driver.sample_time_s - t0 == pytest.approx(elapsed_board, abs=0.01)  # one or two samples
    # The board's 32-bit microsecond counter wraps every 71.6 min; the driver's time goes on.
    driver._absorb(mp.Counts(2**32 - 500, 0, 0, 0))
    before = driver.sample_time_s
    driver._absorb(mp.Counts(1500, 0, 0, 0))
    assert driver.sample_time_s - before == pytest.approx(2000e-6)  # not minus an hour


def test_a_hand_back_during_a_step_ends_the_lending_without_breaking_the_loop(
    driver: SerialMotorDriver,
) -> None:
    driver.enable()

    def experiment() -> Iterator[float]:
        yield 0.1
        driver.hand_back()  # as the service's shutdown does, while the loop's thread runs a step
        yield 0.1
        yield 0.1

    done = driver.take_over("a test", "pan", experiment())  # type: ignore[arg-type]
    assert driver.held_axis == "pan"
    drive(driver, 0.0, 0.0, 0.05)  # nothing may escape tick(): it is the control loop
    assert done.done() and isinstance(done.exception(), DriverFault)
    assert driver.held_by is None and driver.held_axis is None and not driver.faults()


@pytest.mark.slow
def test_friction_id_runs_on_the_emulator(emulator: MotorEmulator) -> None:
    from tracker.workbench.experiments.friction_id import run_friction_id

    # The velocities come from the board's time stamps, so a loaded host's late samples do not
    # bend the lines (they did: viscous 3.8e-4 for 8.5e-4); a watchdog of 1 s, not 100 ms, so a
    # test machine that stalls the host for a tenth of a second does not trip the board.
    d = SerialMotorDriver(parse_driver_url(
        f"serial://{emulator.path}?baud=1000000&rate={RATE_HZ}&watchdog_ms=1000"))
    d.start()
    d.wait_ready(5.0)
    try:
        res = run_friction_id(d, "pan", voltages_per_direction=4)
    finally:
        d.close()
    for line in (res.positive, res.negative):
        assert line.coulomb_nm == pytest.approx(0.052, rel=0.05)
        assert line.viscous_nm_s_per_rad == pytest.approx(8.5e-4, rel=0.1)
    assert not res.shows_stiction()


def test_tracker_motor_emulator_prints_the_device_it_serves(tmp_path: Path) -> None:
    link = tmp_path / "ttyCLI"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "tracker", "motor-emulator", "--pty-link", str(link),
                             "--duration-s", "20", "--quiet"], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()
        assert f"on {link}" in first and "/dev/pts/" in first and f"serial://{link}" in first
        d = new_driver(str(link))
        try:
            assert d.describe()["state"] == "connected"
        finally:
            d.close()
    finally:
        proc.terminate()
        proc.wait(10)
