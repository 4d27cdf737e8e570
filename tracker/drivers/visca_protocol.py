"""VISCA and VISCA-over-IP bytes: the 8-byte header, command and inquiry packets, replies.

Sources checked (public references, not guesses):

- Header, payload types 0x0100 command, 0x0110 inquiry, 0x0111 reply, 0x0120 device setting,
  0x0200 control command (RESET = 0x01), 0x0201 control reply: Sony's VISCA over IP
  (as implemented by vwout/obs-visca-control ``libvisca.lua``); header = type (2 bytes, big
  endian), payload length (2), sequence number (4), then the VISCA packet 0x81 ... 0xFF.
- Packets (PTZOptics G2 NDI|HX manual rev 1.5 part 2/3, the Sony SRG-X400 command list):
  Pan-tiltDrive ``81 01 06 01 VV WW 0p 0q FF`` (VV pan speed 0x01-0x18, WW tilt speed
  0x01-0x14; p: 1 left, 2 right, 3 stop; q: 1 up, 2 down, 3 stop), AbsolutePosition
  ``81 01 06 02 VV WW 0Y 0Y 0Y 0Y 0Z 0Z 0Z 0Z FF``, RelativePosition ``... 06 03 ...``, Home
  ``81 01 06 04 FF``, Pan-tiltLimitSet ``81 01 06 07 00 0W 0Y 0Y 0Y 0Y 0Z 0Z 0Z 0Z FF`` and
  LimitClear ``81 01 06 07 01 0W 07 0F 0F 0F 07 0F 0F 0F FF`` (W: 1 UpRight, 0 DownLeft; the
  Sony SRG-300H and SRG-X400 command lists, the HuddleCamHD VISCA list), CAM_Memory
  set/recall ``81 01 04 3F 01|02 pp FF`` (pp 0-127), CAM_Zoom
  stop ``81 01 04 07 00 FF``, tele/wide variable ``2p``/``3p`` (p 0-7), direct
  ``81 01 04 47 0p 0q 0r 0s FF``; inquiries Pan-tiltPosInq ``81 09 06 12 FF`` ->
  ``90 50 0w 0w 0w 0w 0z 0z 0z 0z FF``, CAM_ZoomPosInq ``81 09 04 47 FF`` ->
  ``90 50 0p 0q 0r 0s FF``, CAM_PowerInq ``81 09 04 00 FF`` -> ``90 50 02|03|04 FF``.
- Replies: ACK ``90 4y FF``, Completion ``90 5y FF`` (inquiries: ``90 50 data FF``, no ACK),
  errors ``90 6y ee FF``: 01 message length, 02 syntax, 03 command buffer full, 04 cancelled,
  05 no socket, 41 not executable. Control replies to a bad header: ``0F 01`` abnormal
  sequence number, ``0F 02`` abnormal message type (Sony's VISCA over IP, as above).

Positions are nibble-encoded: a signed 16-bit value as four bytes ``0h`` each holding 4 bits.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from tracker.errors import DataError

HEADER = struct.Struct(">HHI")
HEADER_LEN = HEADER.size  # 8
MAX_PACKET_LEN = 16  # a VISCA packet is 3-16 bytes
SEQUENCE_MODULO = 2**32

PT_COMMAND = 0x0100
PT_INQUIRY = 0x0110
PT_REPLY = 0x0111
PT_DEVICE_SETTING = 0x0120
PT_CONTROL = 0x0200
PT_CONTROL_REPLY = 0x0201
PAYLOAD_TYPES = (PT_COMMAND, PT_INQUIRY, PT_REPLY, PT_DEVICE_SETTING, PT_CONTROL, PT_CONTROL_REPLY)

CONTROL_RESET = b"\x01"
CONTROL_ERR_SEQUENCE = b"\x0f\x01"
CONTROL_ERR_MESSAGE_TYPE = b"\x0f\x02"

ADDRESS = 0x81  # camera 1 (locked to 1 for VISCA over IP)
REPLY_ADDRESS = 0x90
TERMINATOR = 0xFF

PAN_SPEED_MAX = 0x18
TILT_SPEED_MAX = 0x14
ZOOM_SPEED_MAX = 7
PRESET_MAX = 127

ERR_LENGTH = 0x01
ERR_SYNTAX = 0x02
ERR_BUFFER_FULL = 0x03
ERR_CANCELLED = 0x04
ERR_NO_SOCKET = 0x05
ERR_NOT_EXECUTABLE = 0x41
ERROR_NAMES = {
    ERR_LENGTH: "message length error",
    ERR_SYNTAX: "syntax error",
    ERR_BUFFER_FULL: "command buffer full",
    ERR_CANCELLED: "command cancelled",
    ERR_NO_SOCKET: "no socket",
    ERR_NOT_EXECUTABLE: "command not executable",
}

# Pan-tiltDrive direction bytes.
PAN_LEFT, PAN_RIGHT, PAN_STOP = 0x01, 0x02, 0x03
TILT_UP, TILT_DOWN, TILT_STOP = 0x01, 0x02, 0x03

POWER_ON, POWER_STANDBY, POWER_ERROR = 0x02, 0x03, 0x04

# Pan-tiltLimitSet corners: UpRight sets the upper pan (right) and tilt (up) limits, DownLeft
# the lower ones; LimitClear's position fields are 7FFF (no limit).
LIMIT_DOWN_LEFT, LIMIT_UP_RIGHT = 0x00, 0x01
LIMIT_CLEAR_FIELD = 0x7FFF


@dataclass(frozen=True, slots=True)
class Message:
    """One VISCA-over-IP datagram: payload type, sequence number and payload."""

    payload_type: int
    sequence: int
    payload: bytes


@dataclass(frozen=True, slots=True)
class Reply:
    """A decoded VISCA reply: kind "ack" | "completion" | "error", socket, data or error code."""

    kind: str
    socket: int
    data: bytes = b""
    error: int = 0

    def describe(self) -> str:
        """A short human description (error names from the VISCA tables)."""
        if self.kind == "error":
            return f"{ERROR_NAMES.get(self.error, 'error')} (0x{self.error:02X}, socket {self.socket})"
        return f"{self.kind} (socket {self.socket}{', ' + self.data.hex(' ') if self.data else ''})"


def pack_message(payload_type: int, sequence: int, payload: bytes) -> bytes:
    """The datagram for ``payload`` (header + payload)."""
    return HEADER.pack(payload_type, len(payload), sequence % SEQUENCE_MODULO) + payload


def unpack_message(datagram: bytes) -> Message:
    """Split a datagram into header fields and payload.

    Raises DataError naming the fault: too short, unknown payload type, length mismatch.
    """
    if len(datagram) < HEADER_LEN + 1:
        raise DataError(f"VISCA-over-IP datagram of {len(datagram)} bytes is shorter than a header")
    ptype, length, seq = HEADER.unpack_from(datagram)
    payload = datagram[HEADER_LEN:]
    if ptype not in PAYLOAD_TYPES:
        raise DataError(f"VISCA-over-IP payload type 0x{ptype:04X} is unknown")
    if length != len(payload):
        raise DataError(f"VISCA-over-IP payload length field {length} != {len(payload)} bytes received")
    return Message(ptype, seq, payload)


def encode_nibbles(value: int, n: int = 4) -> bytes:
    """``value`` as ``n`` bytes of one nibble each, two's complement (e.g. -1 -> 0F 0F 0F 0F)."""
    bits = 4 * n
    if not -(1 << (bits - 1)) <= value < (1 << bits):
        raise DataError(f"value {value} does not fit {n} nibbles")
    v = value & ((1 << bits) - 1)
    return bytes((v >> (4 * (n - 1 - i))) & 0x0F for i in range(n))


def decode_nibbles(data: bytes, signed: bool = True) -> int:
    """The inverse of :func:`encode_nibbles` (upper nibbles must be 0)."""
    if any(b & 0xF0 for b in data):
        raise DataError(f"nibble field {data.hex(' ')} has bits in an upper nibble")
    v = 0
    for b in data:
        v = (v << 4) | b
    bits = 4 * len(data)
    if signed and v >= 1 << (bits - 1):
        v -= 1 << bits
    return v


def _packet(*body: int) -> bytes:
    return bytes((ADDRESS, *body, TERMINATOR))


def _check_speed(name: str, value: int, top: int) -> None:
    if not 1 <= value <= top:
        raise DataError(f"{name} speed code {value} is outside 1..{top}")


def pan_tilt_drive(pan_speed: int, tilt_speed: int, pan_dir: int, tilt_dir: int) -> bytes:
    """Pan-tiltDrive: directions PAN_LEFT/RIGHT/STOP, TILT_UP/DOWN/STOP; speeds are codes."""
    _check_speed("pan", pan_speed, PAN_SPEED_MAX)
    _check_speed("tilt", tilt_speed, TILT_SPEED_MAX)
    if pan_dir not in (PAN_LEFT, PAN_RIGHT, PAN_STOP) or tilt_dir not in (TILT_UP, TILT_DOWN, TILT_STOP):
        raise DataError(f"pan-tilt drive direction ({pan_dir}, {tilt_dir}) is not 1, 2 or 3")
    return _packet(0x01, 0x06, 0x01, pan_speed, tilt_speed, pan_dir, tilt_dir)


def pan_tilt_stop() -> bytes:
    """Pan-tiltDrive Stop (speeds are ignored by the camera; sent as 1)."""
    return pan_tilt_drive(1, 1, PAN_STOP, TILT_STOP)


def pan_tilt_position(pan_speed: int, tilt_speed: int, pan: int, tilt: int, relative: bool = False) -> bytes:
    """AbsolutePosition (or RelativePosition) to ``pan``/``tilt`` counts (signed 16-bit)."""
    _check_speed("pan", pan_speed, PAN_SPEED_MAX)
    _check_speed("tilt", tilt_speed, TILT_SPEED_MAX)
    for name, v in (("pan", pan), ("tilt", tilt)):
        if not -0x8000 <= v <= 0x7FFF:
            raise DataError(f"{name} position {v} counts does not fit a signed 16-bit value")
    return _packet(0x01, 0x06, 0x03 if relative else 0x02, pan_speed, tilt_speed,
                   *encode_nibbles(pan), *encode_nibbles(tilt))


def pan_tilt_home() -> bytes:
    """Pan-tiltDrive Home."""
    return _packet(0x01, 0x06, 0x04)


def _check_corner(corner: int) -> None:
    if corner not in (LIMIT_DOWN_LEFT, LIMIT_UP_RIGHT):
        raise DataError(f"pan-tilt limit corner {corner} is not 0 (DownLeft) or 1 (UpRight)")


def pan_tilt_limit_set(corner: int, pan: int, tilt: int) -> bytes:
    """Pan-tiltLimitSet: the ``corner``'s (LIMIT_UP_RIGHT / LIMIT_DOWN_LEFT) pan and tilt limits
    in counts (signed 16-bit, VISCA frame)."""
    _check_corner(corner)
    for name, v in (("pan", pan), ("tilt", tilt)):
        if not -0x8000 <= v <= 0x7FFF:
            raise DataError(f"{name} limit {v} counts does not fit a signed 16-bit value")
    return _packet(0x01, 0x06, 0x07, 0x00, corner, *encode_nibbles(pan), *encode_nibbles(tilt))


def pan_tilt_limit_clear(corner: int) -> bytes:
    """Pan-tiltLimitClear of the ``corner``'s limits."""
    _check_corner(corner)
    clear = encode_nibbles(LIMIT_CLEAR_FIELD)
    return _packet(0x01, 0x06, 0x07, 0x01, corner, *clear, *clear)


def _check_preset(number: int) -> None:
    if not 0 <= number <= PRESET_MAX:
        raise DataError(f"preset {number} is outside 0..{PRESET_MAX}")


def preset_set(number: int) -> bytes:
    """CAM_Memory Set ``number`` (0-127)."""
    _check_preset(number)
    return _packet(0x01, 0x04, 0x3F, 0x01, number)


def preset_recall(number: int) -> bytes:
    """CAM_Memory Recall ``number`` (0-127)."""
    _check_preset(number)
    return _packet(0x01, 0x04, 0x3F, 0x02, number)


def zoom_direct(position: int) -> bytes:
    """CAM_Zoom Direct to ``position`` (0..0x7FFF counts; the camera's own range is smaller)."""
    if not 0 <= position <= 0x7FFF:
        raise DataError(f"zoom position {position} is outside 0..0x7FFF")
    return _packet(0x01, 0x04, 0x47, *encode_nibbles(position))


def zoom_drive(speed: int) -> bytes:
    """CAM_Zoom: tele (speed > 0), wide (< 0) at |speed| 1-7 mapped to p = |speed| - 1, stop (0)."""
    if not -ZOOM_SPEED_MAX - 1 <= speed <= ZOOM_SPEED_MAX + 1:
        raise DataError(f"zoom speed {speed} is outside -8..8")
    if speed == 0:
        return _packet(0x01, 0x04, 0x07, 0x00)
    return _packet(0x01, 0x04, 0x07, (0x20 if speed > 0 else 0x30) | (abs(speed) - 1))


def zoom_stop() -> bytes:
    """CAM_Zoom Stop."""
    return zoom_drive(0)


def inquiry_pan_tilt() -> bytes:
    """Pan-tiltPosInq."""
    return bytes((ADDRESS, 0x09, 0x06, 0x12, TERMINATOR))


def inquiry_zoom() -> bytes:
    """CAM_ZoomPosInq."""
    return bytes((ADDRESS, 0x09, 0x04, 0x47, TERMINATOR))


def inquiry_power() -> bytes:
    """CAM_PowerInq."""
    return bytes((ADDRESS, 0x09, 0x04, 0x00, TERMINATOR))


def decode_reply(payload: bytes) -> Reply:
    """Decode ``90 4y FF`` / ``90 5y .. FF`` / ``90 6y ee FF``; DataError if it is none of them."""
    if len(payload) < 3 or payload[0] != REPLY_ADDRESS or payload[-1] != TERMINATOR:
        raise DataError(f"VISCA reply {payload.hex(' ')} is not 90 .. FF")
    kind_nibble, socket = payload[1] >> 4, payload[1] & 0x0F
    if kind_nibble == 0x4 and len(payload) == 3:
        return Reply("ack", socket)
    if kind_nibble == 0x5:
        return Reply("completion", socket, bytes(payload[2:-1]))
    if kind_nibble == 0x6 and len(payload) == 4:
        return Reply("error", socket, error=payload[2])
    raise DataError(f"VISCA reply {payload.hex(' ')} is not an ACK, completion or error")


def ack(socket: int) -> bytes:
    """``90 4y FF``."""
    return bytes((REPLY_ADDRESS, 0x40 | socket, TERMINATOR))


def completion(socket: int, data: bytes = b"") -> bytes:
    """``90 5y data FF``."""
    return bytes((REPLY_ADDRESS, 0x50 | socket, *data, TERMINATOR))


def error(socket: int, code: int) -> bytes:
    """``90 6y ee FF``."""
    return bytes((REPLY_ADDRESS, 0x60 | socket, code, TERMINATOR))


def decode_pan_tilt(data: bytes) -> tuple[int, int]:
    """Pan and tilt counts from the 8 data bytes of a Pan-tiltPosInq completion."""
    if len(data) != 8:
        raise DataError(f"pan-tilt position reply has {len(data)} data bytes, expected 8")
    return decode_nibbles(data[:4]), decode_nibbles(data[4:])


def decode_zoom(data: bytes) -> int:
    """Zoom counts from the 4 data bytes of a CAM_ZoomPosInq completion."""
    if len(data) != 4:
        raise DataError(f"zoom position reply has {len(data)} data bytes, expected 4")
    return decode_nibbles(data, signed=False)


def split_packets(stream: bytes) -> tuple[list[bytes], bytes]:
    """Split a byte stream (raw VISCA over TCP) at each 0xFF; returns (packets, remainder)."""
    packets: list[bytes] = []
    start = 0
    for i, b in enumerate(stream):
        if b == TERMINATOR:
            packets.append(bytes(stream[start:i + 1]))
            start = i + 1
    return packets, bytes(stream[start:])
