"""Which driver to run, from one configuration string: ``sim``, ``visca+udp://HOST[:PORT]`` or
``serial:///dev/ttyUSB0?baud=115200``.

Forms (case-insensitive scheme):

- ``sim`` — the simulated rig (the default);
- ``visca+udp://HOST[:PORT]`` — Sony VISCA over IP (8-byte header, sequence numbers), port
  52381 by default;
- ``visca+tcp://HOST:PORT`` — raw VISCA packets over TCP (PTZOptics and others on 5678); the
  port is required, there is no standard one;
- ``serial://PATH[?baud=B&rate=HZ&watchdog_ms=MS&link_lost_ms=MS]`` — a DC rig behind a motor controller
  board on a serial port (docs/serial-protocol.md). ``baud`` defaults to 115200; ``rate`` (the
  control samples per second, one exchange each) to the highest of 1000, 500, 250, 200, 100 Hz
  the line carries (``baud ≥ 500·rate``: a sample's reply is up to 40 bytes of 10 bits, at
  most 80 % of the line), so 115200 gives 200 Hz and 1000000 gives 1 kHz; ``watchdog_ms``
  (the board zeroes the command when no command line came for that long) to 100;
  ``link_lost_ms`` (no answer for that long is a lost link: a fault, then reconnection) to 250
  (a loaded host whose pseudo-terminal or USB serial delivers late may need more).

HOST is a name, an IPv4 address or a bracketed IPv6 address. Nothing else (paths, queries,
user names) is accepted for VISCA, so a typo fails at start-up with the reason rather than at
the first command.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from urllib.parse import parse_qsl, urlsplit

from tracker.errors import ConfigError

VISCA_UDP_PORT = 52381
SERIAL_BAUD = 115200
SERIAL_WATCHDOG_MS = 100
SERIAL_LINK_LOST_MS = 250
SERIAL_RATES_HZ = (1000, 500, 250, 200, 100)  # the default rate: the first the line carries
BAUD_PER_HZ = 500  # 40-byte replies of 10 bits each, the line at most 80 % busy
_LABEL = r"[A-Za-z0-9](?:[A-Za-z0-9\-]{0,61}[A-Za-z0-9])?"
_HOST = re.compile(rf"^{_LABEL}(?:\.{_LABEL})*$")


@dataclass(frozen=True, slots=True)
class DriverSpec:
    """A parsed driver setting: kind "sim", "visca" (transport and address) or "serial" (device
    path, baud rate, control rate, board watchdog)."""

    kind: str
    transport: str | None = None  # "udp" | "tcp"
    host: str | None = None
    port: int | None = None
    path: str | None = None
    baud: int | None = None
    rate_hz: int | None = None
    watchdog_ms: int | None = None
    link_lost_ms: int | None = None  # serial: None for the default (SERIAL_LINK_LOST_MS)

    @property
    def url(self) -> str:
        """The canonical form (what the status shows)."""
        if self.kind == "sim":
            return "sim"
        if self.kind == "serial":
            lost = "" if self.link_lost_ms is None else f"&link_lost_ms={self.link_lost_ms}"
            return (f"serial://{self.path}?baud={self.baud}&rate={self.rate_hz}"
                    f"&watchdog_ms={self.watchdog_ms}{lost}")
        host = f"[{self.host}]" if self.host and ":" in self.host else self.host
        return f"visca+{self.transport}://{host}:{self.port}"


def parse_driver_url(value: str) -> DriverSpec:
    """Parse a driver setting; ConfigError saying what is wrong and what is expected."""
    text = value.strip()
    expected = ("expected 'sim', 'visca+udp://HOST[:52381]', 'visca+tcp://HOST:PORT' or "
                "'serial:///dev/ttyUSB0[?baud=115200]'")
    if text.lower() == "sim":
        return DriverSpec("sim")
    if "://" not in text:
        raise ConfigError(f"driver {value!r}: {expected}")
    if text.lower().startswith("serial://"):
        return _parse_serial(value, text)
    try:
        parts = urlsplit(text)
        port = parts.port
    except ValueError as exc:
        raise ConfigError(f"driver {value!r}: {exc}; {expected}") from None
    scheme = parts.scheme.lower()
    if scheme not in ("visca+udp", "visca+tcp"):
        raise ConfigError(f"driver {value!r}: unknown scheme {parts.scheme!r}; {expected}")
    transport = scheme.split("+", 1)[1]
    if parts.username or parts.password:
        raise ConfigError(f"driver {value!r}: user names and passwords are not part of VISCA; {expected}")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise ConfigError(f"driver {value!r}: no path, query or fragment allowed; {expected}")
    host = parts.hostname or ""
    if not host:
        raise ConfigError(f"driver {value!r}: no host; {expected}")
    if ":" not in host and not _HOST.match(host):
        raise ConfigError(f"driver {value!r}: {host!r} is not a host name or address")
    if port is None:
        if transport == "tcp":
            raise ConfigError(f"driver {value!r}: visca+tcp needs a port (PTZOptics: 5678); {expected}")
        port = VISCA_UDP_PORT
    if not 0 < port < 65536:
        raise ConfigError(f"driver {value!r}: port {port} is outside 1..65535")
    return DriverSpec("visca", transport, host, port)


def _parse_serial(value: str, text: str) -> DriverSpec:
    """``serial://PATH[?baud=&rate=&watchdog_ms=&link_lost_ms=]`` (see the module docstring)."""
    parts = urlsplit(text)
    example = "e.g. 'serial:///dev/ttyUSB0?baud=115200'"
    if parts.netloc:
        raise ConfigError(f"driver {value!r}: {parts.netloc!r} where the path should start; "
                          f"a serial device is an absolute path after 'serial://', {example}")
    if not parts.path.startswith("/") or parts.path == "/" or parts.fragment:
        raise ConfigError(f"driver {value!r}: no device path; {example}")
    known = ("baud", "rate", "watchdog_ms", "link_lost_ms")
    query: dict[str, int] = {}
    for key, raw in parse_qsl(parts.query, keep_blank_values=True, strict_parsing=False):
        if key not in known:
            raise ConfigError(f"driver {value!r}: unknown option {key!r}; options are {', '.join(known)}")
        try:
            query[key] = int(raw)
        except ValueError:
            raise ConfigError(f"driver {value!r}: {key}={raw!r} is not a whole number") from None
    if parts.query and not query:
        raise ConfigError(f"driver {value!r}: cannot read the options {parts.query!r}; {example}")
    baud = query.get("baud", SERIAL_BAUD)
    if not 1200 <= baud <= 12_000_000:
        raise ConfigError(f"driver {value!r}: baud {baud} is outside 1200..12000000")
    carried = baud // BAUD_PER_HZ
    rate = query.get("rate") or next((r for r in SERIAL_RATES_HZ if r <= carried), 0)
    if not 10 <= rate <= 2000:
        raise ConfigError(f"driver {value!r}: rate {rate} Hz is outside 10..2000"
                          + ("" if "rate" in query else f" (baud {baud} carries {carried} Hz at most)"))
    if rate > carried:
        raise ConfigError(f"driver {value!r}: {rate} Hz needs baud >= {BAUD_PER_HZ * rate} (each sample's "
                          f"reply is up to 40 bytes); {baud} carries {carried} Hz")
    watchdog = query.get("watchdog_ms", SERIAL_WATCHDOG_MS)
    if not 10 <= watchdog <= 2000:
        raise ConfigError(f"driver {value!r}: watchdog_ms {watchdog} is outside 10..2000")
    lost = query.get("link_lost_ms")
    if lost is not None and not 20 <= lost <= 10_000:
        raise ConfigError(f"driver {value!r}: link_lost_ms {lost} is outside 20..10000")
    return DriverSpec("serial", path=parts.path, baud=baud, rate_hz=rate, watchdog_ms=watchdog,
                      link_lost_ms=lost)
