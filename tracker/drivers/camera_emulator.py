"""A PTZ camera on the network for tests and demos: VISCA over IP on UDP (or raw VISCA on TCP)
on 127.0.0.1, backed by :class:`tracker.drivers.camera_twin.CameraTwin`, with packet loss and
latency injection (``tracker camera-emulator``).

UDP follows Sony's VISCA over IP: a control RESET (0x0200, 0x01) is answered 0x0201 0x01 and
restarts the peer's sequence numbers; a message whose number was already answered gets the
same answers again without running twice (a retransmission); a number older than the last 32
gets the control reply "abnormal sequence number" (0F 01); an unknown payload type gets "abnormal
message type" (0F 02) and a length field that disagrees with the datagram "message length
error" (90 60 01 FF). Loss drops each datagram in each direction with probability ``loss``;
latency delays the handling of each request by half of ``latency_s`` and each answer by the
other half (so a round trip takes ``latency_s`` more). ``drop`` (a test hook) is asked about every
UDP datagram, ``drop(direction, sequence, payload)`` with direction "in" or "out", and drops it
when true, so a test can lose exactly one chosen message. The twin honours Pan-tiltLimitSet and
LimitClear (:mod:`tracker.drivers.camera_responder`); ``limit_commands=False`` (``--no-limits``)
emulates a camera that answers them with a syntax error.
"""

from __future__ import annotations

import asyncio
import contextlib
import random
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from tracker.drivers import visca_protocol as vp
from tracker.drivers.camera_profiles import CameraProfile, get_profile
from tracker.drivers.camera_responder import CameraResponder, ResponderStats
from tracker.drivers.camera_twin import CameraTwin
from tracker.errors import ConfigError

SEQUENCE_WINDOW = 32


@dataclass(slots=True)
class EmulatorStats:
    """Traffic counters (the twin's own counters are in ``responder.stats``)."""

    received: int = 0
    dropped_in: int = 0
    dropped_out: int = 0
    sent: int = 0
    duplicates: int = 0
    resets: int = 0
    sequence_errors: int = 0


@dataclass(slots=True)
class _Peer:
    last: int | None = None
    answers: OrderedDict[int, list[bytes]] | None = None


class CameraEmulator:
    """The emulated camera (see the module docstring). ``await start()``, ``await close()``."""

    def __init__(
        self,
        profile: CameraProfile | str = "generic",
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        transport: str = "udp",
        loss: float = 0.0,
        latency_s: float = 0.0,
        seed: int | None = None,
        tick_s: float = 0.005,
        twin: CameraTwin | None = None,
        limit_commands: bool = True,
    ) -> None:
        if not 0.0 <= loss < 1.0:
            raise ConfigError(f"camera emulator: loss {loss!r} must be in [0, 1)")
        if not 0.0 <= latency_s <= 5.0:
            raise ConfigError(f"camera emulator: latency {latency_s!r} s must be in [0, 5]")
        if transport not in ("udp", "tcp"):
            raise ConfigError(f"camera emulator: transport {transport!r} is not udp or tcp")
        self.profile = get_profile(profile) if isinstance(profile, str) else profile
        self.twin = twin or CameraTwin(self.profile)
        self.responder = CameraResponder(self.twin, limit_commands=limit_commands)
        self.host, self.port, self.transport = host, port, transport
        self.loss, self.latency_s, self.tick_s = float(loss), float(latency_s), float(tick_s)
        self.stats = EmulatorStats()
        self._rng = random.Random(seed)
        self._peers: dict[Any, _Peer] = {}
        self._udp: asyncio.DatagramTransport | None = None
        self._tcp: asyncio.Server | None = None
        self._tcp_writers: set[asyncio.StreamWriter] = set()
        self._ticker: asyncio.Task[None] | None = None
        self.drop: Callable[[str, int, bytes], bool] | None = None

    @property
    def responder_stats(self) -> ResponderStats:
        """What the camera was asked to do."""
        return self.responder.stats

    async def start(self) -> int:
        """Bind and start the clock; returns the port (useful with ``port=0``)."""
        loop = asyncio.get_running_loop()
        if self.transport == "udp":
            transport, _ = await loop.create_datagram_endpoint(
                lambda: _UdpProtocol(self), local_addr=(self.host, self.port))
            self._udp = transport
            self.port = int(transport.get_extra_info("sockname")[1])
        else:
            self._tcp = await asyncio.start_server(self._serve_tcp, self.host, self.port)
            self.port = int(self._tcp.sockets[0].getsockname()[1])
        self._ticker = asyncio.create_task(self._tick(), name="camera-emulator-clock")
        return self.port

    async def close(self) -> None:
        """Stop answering and release the port."""
        if self._ticker is not None:
            self._ticker.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._ticker
            self._ticker = None
        if self._udp is not None:
            self._udp.close()
            self._udp = None
        if self._tcp is not None:
            self._tcp.close()
            for w in list(self._tcp_writers):
                w.close()
            await self._tcp.wait_closed()
            self._tcp = None

    async def _tick(self) -> None:
        loop = asyncio.get_running_loop()
        last = loop.time()
        while True:
            await asyncio.sleep(self.tick_s)
            now = loop.time()
            dt, last = min(now - last, 0.1), now
            steps = max(1, int(dt / 0.005 + 0.999))
            for _ in range(steps):
                pt_done, zoom_done = self.twin.step(dt / steps)
                if pt_done:
                    self.responder.complete("pt", self._send)
                if zoom_done:
                    self.responder.complete("zoom", self._send)

    # -- sending ------------------------------------------------------------------------------
    def _later(self, delay_s: float, fn: Any, *args: Any) -> None:
        if delay_s > 0:
            asyncio.get_running_loop().call_later(delay_s, fn, *args)
        else:
            fn(*args)

    def _send(self, tag: object, payload: bytes) -> None:
        """Send an answer to ``tag``: (addr, seq) on UDP, a StreamWriter on TCP."""
        if isinstance(tag, asyncio.StreamWriter):
            self._later(self.latency_s / 2, self._write_tcp, tag, payload)
            return
        assert isinstance(tag, tuple)
        addr, seq = tag
        peer = self._peers.get(addr)
        if peer is not None and peer.answers is not None and seq in peer.answers:
            peer.answers[seq].append(payload)
        self._later(self.latency_s / 2, self._sendto, addr, vp.PT_REPLY, seq, payload)

    def _sendto(self, addr: Any, ptype: int, seq: int, payload: bytes) -> None:
        if self._udp is None:
            return
        if (self.loss and self._rng.random() < self.loss) or (
                self.drop is not None and self.drop("out", seq, payload)):
            self.stats.dropped_out += 1
            return
        self._udp.sendto(vp.pack_message(ptype, seq, payload), addr)
        self.stats.sent += 1

    def _write_tcp(self, writer: asyncio.StreamWriter, payload: bytes) -> None:
        if not writer.is_closing():
            writer.write(payload)
            self.stats.sent += 1

    # -- UDP ------------------------------------------------------------------------------------
    def datagram(self, data: bytes, addr: Any) -> None:
        """A datagram arrived (after loss, before latency)."""
        self.stats.received += 1
        if (self.loss and self._rng.random() < self.loss) or (
                self.drop is not None and len(data) >= vp.HEADER_LEN
                and self.drop("in", vp.HEADER.unpack_from(data)[2], data[vp.HEADER_LEN:])):
            self.stats.dropped_in += 1
            return
        self._later(self.latency_s / 2, self._handle_datagram, data, addr)

    def _handle_datagram(self, data: bytes, addr: Any) -> None:
        if len(data) < vp.HEADER_LEN:
            self._sendto(addr, vp.PT_CONTROL_REPLY, 0, vp.CONTROL_ERR_MESSAGE_TYPE)
            return
        ptype, length, seq = vp.HEADER.unpack_from(data)
        payload = data[vp.HEADER_LEN:]
        peer = self._peers.setdefault(addr, _Peer(answers=OrderedDict()))
        if ptype == vp.PT_CONTROL:
            if payload == vp.CONTROL_RESET and length == 1:
                peer.last, peer.answers = None, OrderedDict()
                self.stats.resets += 1
                self._later(self.latency_s / 2, self._sendto, addr, vp.PT_CONTROL_REPLY, seq,
                            vp.CONTROL_RESET)
            else:
                self._sendto(addr, vp.PT_CONTROL_REPLY, seq, vp.CONTROL_ERR_MESSAGE_TYPE)
            return
        if ptype not in (vp.PT_COMMAND, vp.PT_INQUIRY):
            self._sendto(addr, vp.PT_CONTROL_REPLY, seq, vp.CONTROL_ERR_MESSAGE_TYPE)
            return
        if length != len(payload):
            self._later(self.latency_s / 2, self._sendto, addr, vp.PT_REPLY, seq, vp.error(0, vp.ERR_LENGTH))
            return
        assert peer.answers is not None
        if seq in peer.answers:  # a retransmission: answer again, do not run twice
            self.stats.duplicates += 1
            for answer in peer.answers[seq]:
                self._later(self.latency_s / 2, self._sendto, addr, vp.PT_REPLY, seq, answer)
            return
        if peer.last is not None and seq <= peer.last - SEQUENCE_WINDOW:
            self.stats.sequence_errors += 1
            self._sendto(addr, vp.PT_CONTROL_REPLY, seq, vp.CONTROL_ERR_SEQUENCE)
            return
        peer.last = seq if peer.last is None else max(peer.last, seq)
        peer.answers[seq] = []
        while len(peer.answers) > SEQUENCE_WINDOW:
            peer.answers.popitem(last=False)
        self.responder.handle(payload, (addr, seq), self._send)

    def expect_sequence_above(self, addr_port: int, sequence: int) -> None:
        """Test hook: behave as if the peer on local port ``addr_port`` had already used numbers up
        to ``sequence`` (its next lower numbers are then refused as abnormal)."""
        for addr, peer in self._peers.items():
            if addr[1] == addr_port:
                peer.last, peer.answers = sequence, OrderedDict()

    # -- TCP ------------------------------------------------------------------------------------
    async def _serve_tcp(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._tcp_writers.add(writer)
        buffer = b""
        try:
            while chunk := await reader.read(256):
                packets, buffer = vp.split_packets(buffer + chunk)
                for packet in packets:
                    self.stats.received += 1
                    self._later(self.latency_s / 2, self.responder.handle, packet, writer, self._send)
        except (ConnectionError, asyncio.CancelledError):
            pass
        finally:
            self._tcp_writers.discard(writer)
            writer.close()


class _UdpProtocol(asyncio.DatagramProtocol):
    def __init__(self, emulator: CameraEmulator) -> None:
        self.emulator = emulator

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        self.emulator.datagram(data, addr)


__all__ = ["CameraEmulator", "EmulatorStats"]
