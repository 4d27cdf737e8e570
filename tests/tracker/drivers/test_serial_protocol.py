"""The serial motor controller's line protocol, the board's behaviour on a fake clock, and
serial:// driver URLs."""

import math

import pytest

from tracker.drivers import motor_protocol as mp
from tracker.drivers.motor_board import MotorBoard
from tracker.drivers.spec import parse_driver_url
from tracker.errors import ConfigError, DriverFault


class FakeClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_crc8_is_crc8_smbus_and_the_table_matches_the_bitwise_form() -> None:
    assert mp.crc8(b"123456789") == 0xF4  # the catalogued check value of CRC-8/SMBUS
    for data in (b"", b"7 C -1500 250", bytes(range(256))):
        assert mp.crc8(data) == mp.crc8_bitwise(data)


def test_a_framed_line_reads_back() -> None:
    raw = mp.frame(17, "C", -1500, 250)
    assert raw.endswith(b"\n") and raw.startswith(b"17 C -1500 250*")
    assert mp.parse_line(raw) == mp.Line(17, "C", ("-1500", "250"))


@pytest.mark.parametrize(
    ("raw", "code"),
    [
        pytest.param(b"17 C -1500 250*00\n", mp.ERR_CHECKSUM, id="wrong-checksum"),
        pytest.param(b"17 C -1500 250\n", mp.ERR_CHECKSUM, id="no-checksum"),
        pytest.param(b"17 C 1*ZZ\n", mp.ERR_CHECKSUM, id="checksum-not-hex"),
        pytest.param(b"1 C " + b"9" * 70 + b"*00\n", mp.ERR_TOO_LONG, id="too-long"),
        pytest.param(mp.frame(300, "E"), mp.ERR_BAD_ARGUMENT, id="sequence-over-255"),
        pytest.param(b"4*%02X\n" % mp.crc8(b"4"), mp.ERR_BAD_ARGUMENT, id="no-verb"),
    ],
)
def test_malformed_lines_are_refused_with_the_protocols_code(raw: bytes, code: int) -> None:
    with pytest.raises(mp.FramingError) as err:
        mp.parse_line(raw)
    assert err.value.code == code


def test_a_garbled_checksum_still_reports_the_sequence_number() -> None:
    with pytest.raises(mp.FramingError) as err:
        mp.parse_line(b"42 E*00\n")
    assert err.value.seq == 42


def board(clock: FakeClock) -> MotorBoard:
    return MotorBoard(clock=clock, board_id="test")


def reply(b: MotorBoard, seq: int, verb: str, *args: object) -> mp.Line:
    return mp.parse_line(b.handle(mp.frame(seq, verb, *args)), mp.MAX_REPLY)


def test_the_hello_names_counts_limit_watchdog_and_boot() -> None:
    b = board(FakeClock())
    hello = mp.parse_hello(reply(b, 1, "H"), "test")
    assert hello.counts_per_rev == (2000, 2000) and hello.vmax_mv == 10_000
    assert hello.watchdog_ms == 100 and hello.board_id == "test" and len(hello.boot) == 8


def test_a_command_is_answered_with_the_counts_and_moves_the_twin() -> None:
    clock = FakeClock()
    b = board(clock)
    assert reply(b, 1, "A", 1).verb == "OK"
    first = mp.parse_counts(reply(b, 2, "C", 3000, 0), "test")
    assert first.armed and first.pan == 0
    for k in range(1, 60):  # 3 V for 60 ms, commanded every 1 ms
        clock.t = k * 1e-3
        counts = mp.parse_counts(reply(b, k % 256, "C", 3000, 0), "test")
    assert counts.pan > 0 and counts.tilt == 0 and counts.t_us == 59_000
    assert counts.pan == b.counts("pan")


def test_the_watchdog_zeroes_the_command_and_disarms_when_the_host_goes_quiet() -> None:
    clock = FakeClock()
    b = board(clock)
    reply(b, 1, "A", 1)
    reply(b, 2, "C", 5000, -5000)
    clock.t = 0.099
    b.catch_up()
    assert b.armed and b.command_mv == {"pan": 5000, "tilt": -5000}
    clock.t = 0.103
    b.catch_up()
    assert not b.armed and b.command_mv == {"pan": 0, "tilt": 0} and b.watchdog_trips == 1
    counts = mp.parse_counts(reply(b, 3, "C", 5000, 0), "test")  # ignored until armed again
    assert not counts.armed and counts.watchdog_tripped and b.command_mv["pan"] == 0
    reply(b, 4, "A", 1)
    assert b.armed and not b.watchdog_tripped


def test_the_watchdog_is_configurable_within_its_range() -> None:
    clock = FakeClock()
    b = board(clock)
    assert reply(b, 1, "W", 20).verb == "OK"
    reply(b, 2, "A", 1)
    reply(b, 3, "C", 1000, 0)
    clock.t = 0.025
    b.catch_up()
    assert not b.armed
    err = reply(b, 4, "W", 5)
    assert err.verb == "ERR" and err.args[0] == str(mp.ERR_OUT_OF_RANGE)


@pytest.mark.parametrize(
    ("verb", "args", "code"),
    [
        pytest.param("X", (), mp.ERR_UNKNOWN_VERB, id="unknown-verb"),
        pytest.param("C", (1,), mp.ERR_BAD_ARGUMENT, id="one-value"),
        pytest.param("C", ("1.5", 0), mp.ERR_BAD_ARGUMENT, id="not-integer"),
        pytest.param("C", (10_001, 0), mp.ERR_OUT_OF_RANGE, id="beyond-vmax"),
        pytest.param("A", (2,), mp.ERR_BAD_ARGUMENT, id="arm-two"),
        pytest.param("E", (1,), mp.ERR_BAD_ARGUMENT, id="read-with-argument"),
    ],
)
def test_the_board_answers_bad_requests_with_err(verb: str, args: tuple[object, ...], code: int) -> None:
    b = board(FakeClock())
    line = reply(b, 9, verb, *args)
    assert line.seq == 9 and line.verb == "ERR" and line.args[0] == str(code)


def test_an_unreadable_line_gets_err_with_sequence_dash() -> None:
    b = board(FakeClock())
    line = mp.parse_line(b.handle(b"garbage\n"), mp.MAX_REPLY)
    assert line.seq is None and line.verb == "ERR" and line.args[0] == str(mp.ERR_CHECKSUM)


def test_a_hello_of_another_protocol_version_is_refused() -> None:
    line = mp.Line(1, "H", ("proto=2", "board=x", "cpr=2000,2000", "vmax=10000", "wd=100", "boot=1"))
    with pytest.raises(DriverFault, match="protocol 2"):
        mp.parse_hello(line, "test")


# -- driver URLs ------------------------------------------------------------------------------


def test_serial_urls_default_to_the_rate_the_line_carries() -> None:
    spec = parse_driver_url("serial:///dev/ttyUSB0?baud=115200")
    assert (spec.kind, spec.path, spec.baud, spec.rate_hz, spec.watchdog_ms) == (
        "serial", "/dev/ttyUSB0", 115200, 200, 100)
    assert parse_driver_url("serial:///dev/ttyACM0").baud == 115200
    fast = parse_driver_url("serial:///dev/ttyACM0?baud=1000000&watchdog_ms=50")
    assert fast.rate_hz == 1000 and fast.watchdog_ms == 50
    assert parse_driver_url(fast.url) == fast


@pytest.mark.parametrize(
    ("url", "match"),
    [
        pytest.param("serial://dev/ttyUSB0", "absolute path", id="two-slashes"),
        pytest.param("serial://", "no device path", id="no-path"),
        pytest.param("serial:///dev/ttyUSB0?speed=9600", "unknown option 'speed'", id="unknown-option"),
        pytest.param("serial:///dev/ttyUSB0?baud=fast", "not a whole number", id="baud-not-number"),
        pytest.param("serial:///dev/ttyUSB0?baud=115200&rate=1000", "needs baud >= 500000",
                     id="rate-too-high"),
        pytest.param("serial:///dev/ttyUSB0?baud=2400", "carries 4 Hz", id="baud-too-low"),
        pytest.param("serial:///dev/ttyUSB0?watchdog_ms=5", "watchdog_ms 5", id="watchdog-too-short"),
    ],
)
def test_bad_serial_urls_say_what_is_wrong(url: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        parse_driver_url(url)


def test_counts_per_rev_and_gear_ratio_give_the_seeds_encoder_step() -> None:
    from tracker.drivers.motor_board import SEED_COUNTS_PER_REV, SEED_GEAR_RATIO
    from tracker.plant.effects.quantization import SEED_ENCODER_STEP_RAD

    assert 2 * math.pi / (SEED_COUNTS_PER_REV * SEED_GEAR_RATIO) == pytest.approx(SEED_ENCODER_STEP_RAD)
