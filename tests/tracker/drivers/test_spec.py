"""The driver setting: sim, visca+udp://HOST[:PORT], visca+tcp://HOST:PORT, and clear refusals."""

import pytest

from tracker.drivers.spec import DriverSpec, parse_driver_url
from tracker.errors import ConfigError


@pytest.mark.parametrize(
    ("value", "spec", "url"),
    [
        ("sim", DriverSpec("sim"), "sim"),
        (" SIM ", DriverSpec("sim"), "sim"),
        ("visca+udp://cam1.local", DriverSpec("visca", "udp", "cam1.local", 52381), "visca+udp://cam1.local:52381"),
        ("visca+udp://10.0.0.7:1259", DriverSpec("visca", "udp", "10.0.0.7", 1259), "visca+udp://10.0.0.7:1259"),
        ("VISCA+TCP://ptz:5678/", DriverSpec("visca", "tcp", "ptz", 5678), "visca+tcp://ptz:5678"),
        ("visca+udp://[::1]:52381", DriverSpec("visca", "udp", "::1", 52381), "visca+udp://[::1]:52381"),
    ],
    ids=["sim", "sim-spaces", "udp-default-port", "udp-port", "tcp", "ipv6"],
)
def test_good_settings_parse(value: str, spec: DriverSpec, url: str) -> None:
    parsed = parse_driver_url(value)
    assert parsed == spec and parsed.url == url


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ("camera", "expected 'sim'"),
        ("http://cam:80", "unknown scheme 'http'"),
        ("visca+udp://", "no host"),
        ("visca+tcp://cam", "needs a port"),
        ("visca+udp://cam:99999", "out of range|outside"),
        ("visca+udp://cam:0", "outside 1..65535"),
        ("visca+udp://cam:52381/x", "no path"),
        ("visca+udp://cam?profile=sony", "no path, query"),
        ("visca+udp://admin:pw@cam", "user names"),
        ("visca+udp://bad_host!", "not a host"),
    ],
    ids=["no-scheme", "http", "no-host", "tcp-no-port", "port-range", "port-0", "path", "query",
         "userinfo", "host"],
)
def test_bad_settings_say_what_is_wrong(value: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        parse_driver_url(value)


def test_a_serial_rigs_lost_link_time_is_an_option() -> None:
    """link_lost_ms: a loaded host whose pseudo-terminal delivers late may need more than 0.25 s."""
    from tracker.drivers.serial_motor import SerialMotorDriver

    plain = parse_driver_url("serial:///dev/ttyUSB0?baud=1000000")
    assert plain.link_lost_ms is None and "link_lost_ms" not in plain.url
    assert SerialMotorDriver(plain)._link_lost_s == 0.25
    spec = parse_driver_url("serial:///dev/ttyUSB0?baud=1000000&link_lost_ms=1000")
    assert spec.link_lost_ms == 1000 and parse_driver_url(spec.url) == spec
    assert SerialMotorDriver(spec)._link_lost_s == 1.0
    with pytest.raises(ConfigError, match="link_lost_ms 5 is outside 20..10000"):
        parse_driver_url("serial:///dev/ttyUSB0?link_lost_ms=5")
