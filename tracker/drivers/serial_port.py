"""A raw serial port (pyserial opens and configures it) read line by line through its file
descriptor with ``select``, so a read waits exactly until a deadline without reconfiguring the
port's timeout (pyserial's ``timeout`` setter calls ``tcsetattr``). POSIX only."""

from __future__ import annotations

import contextlib
import os
import select
import time

from tracker.drivers import motor_protocol as mp


class ReplyTimeout(Exception):
    """No complete line before the deadline."""


class SerialPort:
    """A raw serial port opened with pyserial, read and written through its file descriptor."""

    def __init__(self, path: str, baud: int) -> None:
        import serial  # pyserial

        try:
            self._serial = serial.Serial(path, baudrate=baud, timeout=0, exclusive=True)
        except (serial.SerialException, ValueError) as exc:
            raise OSError(f"cannot open {path}: {exc}") from None
        self.fd: int = self._serial.fileno()
        self._buf = bytearray()
        self._serial.reset_input_buffer()

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self.fd, view)
            view = view[n:]

    def read_line(self, deadline_s: float) -> bytes:
        """The next line (with its newline); ReplyTimeout at ``deadline_s`` (perf_counter), OSError
        when the port is gone.

        What has already arrived is read even when the deadline has passed: a thread that was
        held up after its request (the interpreter lock, a loaded machine) finds the board's
        answer waiting, which is no time-out of the board's (it counted as one, and two of them
        0.25 s apart were a "link lost" fault on a busy test machine)."""
        polled_late = False  # past the deadline: one look at what is there, then the time-out
        while True:
            end = self._buf.find(b"\n")
            if end >= 0:
                line = bytes(self._buf[: end + 1])
                del self._buf[: end + 1]
                return line
            if len(self._buf) > 4 * mp.MAX_REPLY:
                self._buf.clear()  # noise without newlines
            remaining = deadline_s - time.perf_counter()
            if remaining <= 0:
                if polled_late:
                    raise ReplyTimeout
                polled_late, remaining = True, 0.0
            ready, _, _ = select.select([self.fd], [], [], remaining)
            if not ready:
                raise ReplyTimeout
            data = os.read(self.fd, 4096)
            if not data:
                raise OSError("the port hung up")
            self._buf += data

    def flush_input(self) -> None:
        self._buf.clear()
        with contextlib.suppress(OSError):
            while select.select([self.fd], [], [], 0)[0] and os.read(self.fd, 4096):
                pass

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._serial.close()
