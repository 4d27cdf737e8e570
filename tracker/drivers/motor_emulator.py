"""The motor controller emulator: a :class:`~tracker.drivers.motor_board.MotorBoard` behind a
pseudo-terminal, so the serial driver talks to it through a real tty.

``MotorEmulator().start()`` opens a pty (``os.openpty``), puts it in raw mode, optionally
points a symlink (``pty_link``, e.g. /tmp/ttyRIG) at the device so a restarted emulator keeps
the same name, and answers lines in a thread. ``stall(seconds)`` makes it swallow lines
without answering (a hung board); ``close()`` hangs the line up (the driver sees the port go).
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
import tty
from pathlib import Path

from tracker.drivers import motor_protocol as mp
from tracker.drivers.motor_board import MotorBoard
from tracker.errors import ConfigError


class MotorEmulator:
    """A motor controller on a pseudo-terminal (see the module docstring)."""

    def __init__(self, board: MotorBoard | None = None, pty_link: str | Path | None = None) -> None:
        self.board = board or MotorBoard()
        self.pty_link = None if pty_link is None else Path(pty_link)
        self.device: str | None = None
        self._master = -1
        self._slave = -1
        self._thread: threading.Thread | None = None
        self._closing = threading.Event()
        self._quiet_until = 0.0
        self.swallowed = 0

    @property
    def path(self) -> str:
        """What a driver opens: the link when there is one, else the pty device."""
        if self.pty_link is not None:
            return str(self.pty_link)
        if self.device is None:
            raise ConfigError("motor emulator: not started")
        return self.device

    def start(self) -> str:
        """Open the pty and answer in a thread; returns :attr:`path`."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line editing, no CR/LF translation
        tty.setraw(self._master)
        self.device = os.ttyname(self._slave)
        if self.pty_link is not None:
            tmp = self.pty_link.with_name(self.pty_link.name + ".new")
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            tmp.symlink_to(self.device)
            tmp.replace(self.pty_link)  # atomic: a driver never sees the name missing
        self._closing.clear()
        self._thread = threading.Thread(target=self._serve, name="motor-emulator", daemon=True)
        self._thread.start()
        return self.path

    def stall(self, seconds: float) -> None:
        """Swallow every line for ``seconds`` (a board that stopped answering)."""
        self._quiet_until = time.monotonic() + float(seconds)

    def close(self) -> None:
        """Stop answering and hang up (the driver's reads fail); remove the link if it is ours."""
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1
        if self.pty_link is not None and self.device is not None:
            with contextlib.suppress(OSError):
                if os.readlink(self.pty_link) == self.device:
                    self.pty_link.unlink()

    def _serve(self) -> None:
        buf = bytearray()
        while not self._closing.is_set():
            ready, _, _ = select.select([self._master], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(self._master, 4096)
            except OSError:  # nobody has the slave open: wait for the next driver
                time.sleep(0.01)
                continue
            buf += data
            while True:
                end = buf.find(b"\n")
                if end < 0:
                    if len(buf) > 4 * mp.MAX_LINE:  # a flood without newlines: answer and drop it
                        self._answer(bytes(buf))
                        buf.clear()
                    break
                line = bytes(buf[: end + 1])
                del buf[: end + 1]
                self._answer(line)

    def _answer(self, line: bytes) -> None:
        if time.monotonic() < self._quiet_until:
            self.swallowed += 1
            return
        reply = self.board.handle(line)
        with contextlib.suppress(OSError):
            os.write(self._master, reply)
