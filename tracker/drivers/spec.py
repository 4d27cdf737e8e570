"""Which driver to run, from one configuration string: ``sim`` or ``visca+udp://HOST[:PORT]``.

Forms (case-insensitive scheme):

- ``sim`` — the simulated rig (the default);
- ``visca+udp://HOST[:PORT]`` — Sony VISCA over IP (8-byte header, sequence numbers), port
  52381 by default;
- ``visca+tcp://HOST:PORT`` — raw VISCA packets over TCP (PTZOptics and others on 5678); the
  port is required, there is no standard one.

HOST is a name, an IPv4 address or a bracketed IPv6 address. Nothing else (paths, queries,
user names) is accepted, so a typo fails at start-up with the reason rather than at the first
command.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from urllib.parse import urlsplit

from tracker.errors import ConfigError

VISCA_UDP_PORT = 52381
_LABEL = r"[A-Za-z0-9](?:[A-Za-z0-9\-]{0,61}[A-Za-z0-9])?"
_HOST = re.compile(rf"^{_LABEL}(?:\.{_LABEL})*$")


@dataclass(frozen=True, slots=True)
class DriverSpec:
    """A parsed driver setting: kind "sim" or "visca", and for VISCA the transport and address."""

    kind: str
    transport: str | None = None  # "udp" | "tcp"
    host: str | None = None
    port: int | None = None

    @property
    def url(self) -> str:
        """The canonical form (what the status shows)."""
        if self.kind == "sim":
            return "sim"
        host = f"[{self.host}]" if self.host and ":" in self.host else self.host
        return f"visca+{self.transport}://{host}:{self.port}"


def parse_driver_url(value: str) -> DriverSpec:
    """Parse a driver setting; ConfigError saying what is wrong and what is expected."""
    text = value.strip()
    expected = "expected 'sim', 'visca+udp://HOST[:52381]' or 'visca+tcp://HOST:PORT'"
    if text.lower() == "sim":
        return DriverSpec("sim")
    if "://" not in text:
        raise ConfigError(f"driver {value!r}: {expected}")
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
