"""What a VISCA camera answers: decodes one VISCA packet, runs it on the twin and returns the
replies, with the camera's two command sockets (a move holds one until it completes).

Network-free and clock-free: :class:`tracker.drivers.camera_emulator.CameraEmulator` feeds it
packets and steps the twin. Malformed or unknown packets get the VISCA error replies a camera
sends (syntax error 90 60 02 FF, message length 90 60 01 FF); a move when both sockets are
busy gets "command buffer full" (90 60 03 FF); a move that another move replaces gets
"command cancelled" (90 6y 04 FF) on its own socket. Pan-tiltLimitSet / LimitClear set the
twin's own limits (a value outside the mechanical range is a syntax error, limits that leave
no range are not executable); with ``limit_commands=False`` the camera does not know them
(syntax error), as a model without the command.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from tracker.drivers import visca_protocol as vp
from tracker.drivers.camera_twin import CameraTwin
from tracker.errors import DataError

SOCKETS = (1, 2)


@dataclass(slots=True)
class Job:
    """A command still running on a socket: kind "pt" (pan-tilt move) or "zoom"; ``tag`` lets
    the caller route its Completion (the UDP peer and sequence number)."""

    kind: str
    socket: int
    tag: object


@dataclass(slots=True)
class ResponderStats:
    """What the camera was asked (tests read these)."""

    motion_commands: int = 0  # anything that makes the head or zoom move
    stop_commands: int = 0
    inquiries: int = 0
    errors: int = 0


class _Syntax(Exception):
    """The packet is not a command this camera knows (internal)."""


class CameraResponder:
    """Packets in, replies out (see the module docstring)."""

    def __init__(self, twin: CameraTwin, *, limit_commands: bool = True) -> None:
        self.twin = twin
        self.limit_commands = limit_commands
        self.jobs: dict[int, Job] = {}
        self.stats = ResponderStats()

    def handle(self, packet: bytes, tag: object, send: Callable[[object, bytes], None]) -> None:
        """Answer ``packet``; every reply goes through ``send(tag, reply)`` (a cancelled job's
        reply goes to that job's tag)."""
        if not 3 <= len(packet) <= vp.MAX_PACKET_LEN:
            self.stats.errors += 1
            send(tag, vp.error(0, vp.ERR_LENGTH))
            return
        if packet[0] != vp.ADDRESS or packet[-1] != vp.TERMINATOR or vp.TERMINATOR in packet[:-1]:
            self.stats.errors += 1
            send(tag, vp.error(0, vp.ERR_SYNTAX))
            return
        body = packet[1:-1]
        try:
            if body[:1] == b"\x09":
                send(tag, vp.completion(0, self._inquiry(body[1:])))
                self.stats.inquiries += 1
            elif body[:1] == b"\x01":
                self._command(body[1:], tag, send)
            else:
                raise _Syntax
        except (_Syntax, DataError, IndexError):
            self.stats.errors += 1
            send(tag, vp.error(0, vp.ERR_SYNTAX))

    def complete(self, kind: str, send: Callable[[object, bytes], None]) -> None:
        """The twin finished a ``kind`` move: send its Completion and free the socket."""
        for socket, job in list(self.jobs.items()):
            if job.kind == kind:
                del self.jobs[socket]
                send(job.tag, vp.completion(socket))

    # -- inquiries --------------------------------------------------------------------------
    def _inquiry(self, body: bytes) -> bytes:
        if body == b"\x06\x12":
            pan, tilt = self.twin.position_counts()
            return vp.encode_nibbles(pan) + vp.encode_nibbles(tilt)
        if body == b"\x04\x47":
            return vp.encode_nibbles(self.twin.zoom_counts())
        if body == b"\x04\x00":
            return bytes((vp.POWER_ON if self.twin.power_on else vp.POWER_STANDBY,))
        raise _Syntax

    # -- commands ---------------------------------------------------------------------------
    def _command(self, body: bytes, tag: object, send: Callable[[object, bytes], None]) -> None:
        twin = self.twin
        cat, cmd, args = body[0], body[1], body[2:]
        if (cat, cmd) == (0x04, 0x00) and args in (b"\x02", b"\x03"):
            twin.power_on = args == b"\x02"
            self._immediate(tag, send)
            return
        if not twin.power_on:
            send(tag, vp.error(0, vp.ERR_NOT_EXECUTABLE))
            return
        if (cat, cmd) == (0x06, 0x01) and len(args) == 4:
            pan_code, tilt_code, pan_dir, tilt_dir = args
            vp.pan_tilt_drive(pan_code, tilt_code, pan_dir, tilt_dir)  # validates (DataError)
            self._cancel("pt", send)
            twin.drive(pan_code, tilt_code, pan_dir, tilt_dir)
            if (pan_dir, tilt_dir) == (vp.PAN_STOP, vp.TILT_STOP):
                self.stats.stop_commands += 1
            else:
                self.stats.motion_commands += 1
            self._immediate(tag, send)
        elif (cat, cmd) in ((0x06, 0x02), (0x06, 0x03)) and len(args) == 10:
            pan_code, tilt_code = args[0], args[1]
            pan, tilt = vp.decode_nibbles(args[2:6]), vp.decode_nibbles(args[6:10])
            vp.pan_tilt_position(pan_code, tilt_code, pan, tilt)  # validates
            q = twin.profile.rad_per_count
            if cmd == 0x03:
                pan_rad = twin.axes["pan"].motor_rad + pan * q
                tilt_rad = twin.axes["tilt"].motor_rad + tilt * q
            else:
                pan_rad, tilt_rad = pan * q, tilt * q
            self._start("pt", tag, send, lambda: twin.move_to(pan_rad, tilt_rad, pan_code, tilt_code))
        elif (cat, cmd) == (0x06, 0x07) and len(args) == 10 and self.limit_commands:
            self._limit(args, tag, send)
        elif (cat, cmd) == (0x06, 0x04) and not args:
            self._start("pt", tag, send, lambda: twin.move_to(0.0, 0.0, 0x18, 0x14))
        elif (cat, cmd) == (0x04, 0x3F) and len(args) == 2 and args[0] in (0x01, 0x02):
            number = args[1]
            if number > vp.PRESET_MAX:
                raise _Syntax
            if args[0] == 0x01:
                twin.store_preset(number)
                self._immediate(tag, send)
                return
            if number not in twin.presets:
                send(tag, vp.error(0, vp.ERR_NOT_EXECUTABLE))
                return
            pan_rad, tilt_rad, zoom = twin.presets[number]

            def recall() -> None:
                twin.move_to(pan_rad, tilt_rad, 0x18, 0x14)
                twin.zoom_to(zoom)

            self._start("pt", tag, send, recall)
        elif (cat, cmd) == (0x04, 0x47) and len(args) == 4:
            counts = vp.decode_nibbles(args, signed=False)
            self._start("zoom", tag, send, lambda: twin.zoom_to(counts))
        elif (cat, cmd) == (0x04, 0x07) and len(args) == 1:
            x = args[0]
            if x == 0x00:
                self._cancel("zoom", send)
                twin.zoom_stop()
                self.stats.stop_commands += 1
            elif x in (0x02, 0x03) or x >> 4 in (0x2, 0x3):
                p = 3 if x in (0x02, 0x03) else x & 0x0F
                if p > vp.ZOOM_SPEED_MAX:
                    raise _Syntax
                self._cancel("zoom", send)
                twin.zoom_drive(p, tele=(x == 0x02 or x >> 4 == 0x2))
                self.stats.motion_commands += 1
            else:
                raise _Syntax
            self._immediate(tag, send)
        else:
            raise _Syntax

    def _limit(self, args: bytes, tag: object, send: Callable[[object, bytes], None]) -> None:
        action, corner = args[0], args[1]
        if action not in (0x00, 0x01) or corner not in (vp.LIMIT_DOWN_LEFT, vp.LIMIT_UP_RIGHT):
            raise _Syntax
        pan, tilt = vp.decode_nibbles(args[2:6]), vp.decode_nibbles(args[6:10])
        if action == 0x01:  # LimitClear: both fields 7FFF
            if (pan, tilt) != (vp.LIMIT_CLEAR_FIELD, vp.LIMIT_CLEAR_FIELD):
                raise _Syntax
            done = self.twin.set_limit(corner == vp.LIMIT_UP_RIGHT, None, None)
        else:
            q = self.twin.profile.rad_per_count
            done = self.twin.set_limit(corner == vp.LIMIT_UP_RIGHT, pan * q, tilt * q)
        if not done:
            self.stats.errors += 1
            send(tag, vp.error(0, vp.ERR_NOT_EXECUTABLE))
            return
        self._immediate(tag, send)

    def _immediate(self, tag: object, send: Callable[[object, bytes], None]) -> None:
        socket = next((s for s in SOCKETS if s not in self.jobs), SOCKETS[0])
        send(tag, vp.ack(socket))
        send(tag, vp.completion(socket))

    def _cancel(self, kind: str, send: Callable[[object, bytes], None]) -> None:
        for socket, job in list(self.jobs.items()):
            if job.kind == kind:
                del self.jobs[socket]
                send(job.tag, vp.error(socket, vp.ERR_CANCELLED))

    def _start(
        self, kind: str, tag: object, send: Callable[[object, bytes], None], run: Callable[[], None]
    ) -> None:
        self._cancel(kind, send)
        free = [s for s in SOCKETS if s not in self.jobs]
        if not free:
            self.stats.errors += 1
            send(tag, vp.error(0, vp.ERR_BUFFER_FULL))
            return
        run()
        self.stats.motion_commands += 1
        self.jobs[free[0]] = Job(kind, free[0], tag)
        send(tag, vp.ack(free[0]))
