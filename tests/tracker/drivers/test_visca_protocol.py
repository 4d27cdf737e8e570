"""VISCA bytes: packets as the manuals print them, nibble positions, header and reply decoding."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tracker.drivers import visca_protocol as vp
from tracker.errors import DataError


@pytest.mark.parametrize(
    ("packet", "expected"),
    [
        (vp.pan_tilt_drive(0x18, 0x14, vp.PAN_LEFT, vp.TILT_UP), "81 01 06 01 18 14 01 01 ff"),
        (vp.pan_tilt_drive(5, 3, vp.PAN_RIGHT, vp.TILT_STOP), "81 01 06 01 05 03 02 03 ff"),
        (vp.pan_tilt_stop(), "81 01 06 01 01 01 03 03 ff"),
        (vp.pan_tilt_position(0x18, 0x14, 0x0990, -1), "81 01 06 02 18 14 00 09 09 00 0f 0f 0f 0f ff"),
        (vp.pan_tilt_position(1, 1, -2448, 0, relative=True), "81 01 06 03 01 01 0f 06 07 00 00 00 00 00 ff"),
        (vp.pan_tilt_home(), "81 01 06 04 ff"),
        (vp.preset_set(127), "81 01 04 3f 01 7f ff"),
        (vp.preset_recall(2), "81 01 04 3f 02 02 ff"),
        (vp.zoom_direct(0x4000), "81 01 04 47 04 00 00 00 ff"),
        (vp.zoom_drive(8), "81 01 04 07 27 ff"),
        (vp.zoom_drive(-1), "81 01 04 07 30 ff"),
        (vp.zoom_stop(), "81 01 04 07 00 ff"),
        (vp.inquiry_pan_tilt(), "81 09 06 12 ff"),
        (vp.inquiry_zoom(), "81 09 04 47 ff"),
        (vp.inquiry_power(), "81 09 04 00 ff"),
    ],
    ids=["drive-upleft", "drive-right", "stop", "absolute", "relative", "home", "preset-set",
         "preset-recall", "zoom-direct", "zoom-tele", "zoom-wide", "zoom-stop", "inq-pt", "inq-zoom",
         "inq-power"],
)
def test_packets_match_the_command_lists(packet: bytes, expected: str) -> None:
    assert packet.hex(" ") == expected


@given(st.integers(-0x8000, 0x7FFF))
def test_signed_positions_round_trip_through_nibbles(value: int) -> None:
    data = vp.encode_nibbles(value)
    assert len(data) == 4 and all(b <= 0x0F for b in data)
    assert vp.decode_nibbles(data) == value


def test_header_is_type_length_sequence_big_endian() -> None:
    datagram = vp.pack_message(vp.PT_INQUIRY, 0x01020304, vp.inquiry_pan_tilt())
    assert datagram[:8].hex(" ") == "01 10 00 05 01 02 03 04"
    msg = vp.unpack_message(datagram)
    assert (msg.payload_type, msg.sequence, msg.payload) == (vp.PT_INQUIRY, 0x01020304, vp.inquiry_pan_tilt())


@pytest.mark.parametrize(
    ("datagram", "match"),
    [
        (b"\x01\x00\x00", "shorter than a header"),
        (bytes.fromhex("0300 0001 00000001 01"), "payload type 0x0300"),
        (bytes.fromhex("0100 0009 00000001 81 09 06 12 ff"), "length field 9"),
    ],
    ids=["short", "type", "length"],
)
def test_bad_headers_are_refused_by_name(datagram: bytes, match: str) -> None:
    with pytest.raises(DataError, match=match):
        vp.unpack_message(datagram)


@pytest.mark.parametrize(
    ("payload", "kind", "socket", "error"),
    [("90 41 ff", "ack", 1, 0), ("90 52 ff", "completion", 2, 0), ("90 60 02 ff", "error", 0, 2),
     ("90 61 41 ff", "error", 1, 0x41)],
    ids=["ack", "completion", "syntax", "not-executable"],
)
def test_replies_decode(payload: str, kind: str, socket: int, error: int) -> None:
    reply = vp.decode_reply(bytes.fromhex(payload))
    assert (reply.kind, reply.socket, reply.error) == (kind, socket, error)


def test_position_reply_decodes_signed_counts() -> None:
    reply = vp.decode_reply(bytes.fromhex("90 50 0f 06 07 00 00 09 09 00 ff"))
    assert vp.decode_pan_tilt(reply.data) == (-2448, 0x0990)


@pytest.mark.parametrize(
    "make", [lambda: vp.pan_tilt_drive(0, 1, 1, 1), lambda: vp.pan_tilt_drive(1, 0x15, 1, 1),
             lambda: vp.pan_tilt_drive(1, 1, 4, 1), lambda: vp.preset_set(128),
             lambda: vp.pan_tilt_position(1, 1, 0x8000, 0)],
    ids=["pan-speed-0", "tilt-speed-21", "direction-4", "preset-128", "position-overflow"],
)
def test_out_of_range_parameters_are_refused(make: object) -> None:
    with pytest.raises(DataError):
        make()  # type: ignore[operator]


def test_tcp_stream_splits_at_terminators() -> None:
    packets, rest = vp.split_packets(bytes.fromhex("90 41 ff 90 51 ff 90 50"))
    assert [p.hex(" ") for p in packets] == ["90 41 ff", "90 51 ff"] and rest == bytes.fromhex("90 50")
