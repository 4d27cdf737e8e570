"""The serial motor controller's ASCII line protocol: framing, CRC-8, the lines each side sends.

One line each way per request (docs/serial-protocol.md)::

    <seq> <verb>[ <arg>...]*<crc>\\n

``seq`` is a decimal 0..255 the board echoes in its reply; ``crc`` is the CRC-8 (polynomial
0x07, initial value 0, no reflection: CRC-8/SMBUS) of every byte before the ``*``, as two
upper-case hex digits. Host verbs: ``H`` hello, ``W <ms>`` watchdog, ``A <0|1>`` arm,
``C <pan_mV> <tilt_mV>`` command (answered with the counts), ``E`` read the counts,
``L <pan_lo> <pan_hi> <tilt_lo> <tilt_hi>`` limits the board enforces (counts; ``L`` alone: off),
``B <pan> <tilt>`` the braking zone's deceleration (counts/s², 0: none). Board
replies: ``H key=value ...``, ``OK``, ``E <t_us> <pan_counts> <tilt_counts> <flags>`` and
``ERR <code> <text>``.
"""

from __future__ import annotations

from dataclasses import dataclass

from tracker.errors import DriverFault

PROTOCOL_VERSION = 1
MAX_LINE = 64  # bytes of a host line, newline included: the board's buffer (longer: ERR 2)
MAX_REPLY = 128  # bytes of a board line, newline included

# Error codes of ``ERR <code> <text>``.
ERR_CHECKSUM = 1
ERR_TOO_LONG = 2
ERR_UNKNOWN_VERB = 3
ERR_BAD_ARGUMENT = 4
ERR_OUT_OF_RANGE = 5

# Bits of the ``flags`` field (hex) of an ``E`` reply.
FLAG_ARMED = 0x01
FLAG_WATCHDOG = 0x02  # the watchdog zeroed the command and disarmed; cleared by ``A 1``


def crc8_bitwise(data: bytes) -> int:
    """CRC-8/SMBUS (poly 0x07, init 0x00) of ``data``, bit by bit: the board's few lines of C."""
    crc = 0
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


_CRC_TABLE = tuple(crc8_bitwise(bytes([i])) for i in range(256))


def crc8(data: bytes) -> int:
    """CRC-8/SMBUS of ``data`` by table (the same value; ~10x faster in Python, which matters at
    four checksums per sample)."""
    crc = 0
    table = _CRC_TABLE
    for byte in data:
        crc = table[crc ^ byte]
    return crc


def frame(seq: int | str, verb: str, *args: object) -> bytes:
    """One line: ``<seq> <verb> <args>*<crc>\\n`` (``seq`` "-" for a reply to an unreadable line)."""
    body = " ".join([str(seq), verb, *(str(a) for a in args)]).encode("ascii")
    return body + b"*%02X\n" % crc8(body)


@dataclass(frozen=True, slots=True)
class Line:
    """A received line, checked: ``seq`` (None when the sender wrote "-"), verb and arguments."""

    seq: int | None
    verb: str
    args: tuple[str, ...]


class FramingError(ValueError):
    """A line that cannot be used; ``code`` is the protocol's error code, ``seq`` what was read."""

    def __init__(self, code: int, text: str, seq: int | None = None) -> None:
        super().__init__(text)
        self.code, self.text, self.seq = code, text, seq


def _seq_of(token: str) -> int | None:
    if token.isdigit() and len(token) <= 3 and int(token) <= 255:
        return int(token)
    return None


def parse_line(raw: bytes, max_len: int = MAX_LINE) -> Line:
    """Check a line's framing and checksum (the trailing newline is optional)."""
    text = raw.rstrip(b"\r\n")
    if len(text) + 1 > max_len:
        raise FramingError(ERR_TOO_LONG, f"line of {len(text) + 1} bytes (at most {max_len})",
                           _seq_of(text.split(b" ", 1)[0].decode("ascii", "replace")))
    body, star, tail = text.rpartition(b"*")
    try:
        words = (body if star else text).decode("ascii").split()
    except UnicodeDecodeError:
        raise FramingError(ERR_BAD_ARGUMENT, "not ASCII") from None
    seq = _seq_of(words[0]) if words else None
    if not star or len(tail) != 2:
        raise FramingError(ERR_CHECKSUM, "no *CC checksum", seq)
    try:
        got = int(tail, 16)
    except ValueError:
        raise FramingError(ERR_CHECKSUM, f"checksum {tail.decode('ascii', 'replace')!r} is not hex",
                           seq) from None
    if got != crc8(body):
        raise FramingError(ERR_CHECKSUM, f"checksum {got:02X}, expected {crc8(body):02X}", seq)
    if len(words) < 2 or (seq is None and words[0] != "-"):
        raise FramingError(ERR_BAD_ARGUMENT, "expected '<seq 0-255> <verb> ...'", seq)
    return Line(seq, words[1], tuple(words[2:]))


@dataclass(frozen=True, slots=True)
class Hello:
    """The board's identity line: protocol, board name and id, counts per motor revolution per
    axis, the command limit (mV), the watchdog (ms) and a boot nonce that changes at power-up."""

    protocol: int
    board: str
    board_id: str
    counts_per_rev: tuple[int, int]
    vmax_mv: int
    watchdog_ms: int
    boot: str


@dataclass(frozen=True, slots=True)
class Counts:
    """An ``E`` reply: the board's time (µs, wraps at 2**32), both encoders' counts, flags."""

    t_us: int
    pan: int
    tilt: int
    flags: int

    @property
    def armed(self) -> bool:
        return bool(self.flags & FLAG_ARMED)

    @property
    def watchdog_tripped(self) -> bool:
        return bool(self.flags & FLAG_WATCHDOG)


def parse_hello(line: Line, where: str) -> Hello:
    """The ``H`` reply's fields; DriverFault naming ``where`` when one is missing or malformed."""
    fields = dict(a.partition("=")[::2] for a in line.args)
    try:
        cpr = tuple(int(c) for c in fields["cpr"].split(","))
        hello = Hello(int(fields["proto"]), fields["board"], fields.get("id", "?"),
                      (cpr[0], cpr[1]), int(fields["vmax"]), int(fields["wd"]), fields["boot"])
    except (KeyError, ValueError, IndexError) as exc:
        raise DriverFault(f"{where}: hello {' '.join(line.args)!r} is malformed ({exc})") from None
    if hello.protocol != PROTOCOL_VERSION:
        raise DriverFault(f"{where}: board speaks protocol {hello.protocol}, this driver {PROTOCOL_VERSION}")
    if min(hello.counts_per_rev) <= 0 or hello.vmax_mv <= 0:
        raise DriverFault(f"{where}: hello gives cpr={fields['cpr']} vmax={fields['vmax']}; both must be > 0")
    return hello


def parse_counts(line: Line, where: str) -> Counts:
    """An ``E`` reply; DriverFault when malformed."""
    try:
        t_us, pan, tilt, flags = line.args
        return Counts(int(t_us), int(pan), int(tilt), int(flags, 16))
    except ValueError:
        raise DriverFault(f"{where}: counts reply {' '.join(line.args)!r} is malformed") from None


def hello_reply(seq: int, hello: Hello) -> bytes:
    """The board's answer to ``H`` (the emulator's; a real board prints the same fields)."""
    return frame(seq, "H", f"proto={hello.protocol}", f"board={hello.board}", f"id={hello.board_id}",
                 f"cpr={hello.counts_per_rev[0]},{hello.counts_per_rev[1]}", f"vmax={hello.vmax_mv}",
                 f"wd={hello.watchdog_ms}", f"boot={hello.boot}")
