"""The VISCA transports under asyncio: Sony's VISCA over IP (UDP, sequence numbers) and raw
VISCA over TCP (PTZOptics and others), both answering ``request(packet) -> Reply``.

UDP (:class:`UdpLink`): every message carries a sequence number; replies carry the number of
the message they answer, so several requests can be in flight (the driver's position inquiry
and its drive command every cycle). A request without an answer within ``timeout_s`` is sent
again *with the same number* (a camera that has seen it replays its answer instead of running
it twice) up to ``retries`` times. A control reply "abnormal sequence number" (0F 01) makes
the link send RESET (payload type 0x0200, 0x01), restart its numbers and send the request again.
While waiting for a command's Completion the link re-asks with the same number every 0.5 s;
a camera that has run the command and lost its Completion may answer that with "abnormal
sequence number" (Sony's delivery-confirmation table: "the command has been performed; if the
result by the Completion is needed, retransmit by updating the sequence number"), so the link
then sends the command again under a new number, until ``completion_timeout_s`` has passed
since the first send. Hence ``completion=True`` is only for commands that may run twice with
the same effect (absolute moves, home, preset recall, zoom direct: the driver's only users).

TCP (:class:`TcpLink`): no header and no numbers; replies come back in order, so one request
is in flight at a time. Command completions arrive later, tagged with the socket the ACK named.

Errors: :class:`ViscaError` (the camera answered with an error reply) and :class:`LinkTimeout`
(no answer), both :class:`tracker.errors.DriverFault`.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Protocol

from tracker.drivers import visca_protocol as vp
from tracker.errors import DataError, DriverFault


class ViscaError(DriverFault):
    """The camera answered a request with a VISCA error reply (``code`` from the VISCA tables)."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class LinkTimeout(DriverFault):
    """No answer from the camera within the time-out, after every retransmission."""


@dataclass(slots=True)
class LinkStats:
    """Counters and round-trip times of one link (the status and the benchmark read them)."""

    sent: int = 0
    retransmits: int = 0
    timeouts: int = 0
    sequence_resets: int = 0
    completion_renewals: int = 0  # commands sent again under a new number for their Completion
    errors: int = 0
    rtt_s: deque[float] = field(default_factory=lambda: deque(maxlen=500))

    def rtt_percentile_ms(self, q: float) -> float | None:
        """The ``q``-th percentile (0-100) of the recent round trips (ms), None before any."""
        if not self.rtt_s:
            return None
        values = sorted(self.rtt_s)
        i = min(len(values) - 1, max(0, round(q / 100.0 * (len(values) - 1))))
        return 1e3 * values[i]


class ViscaLink(Protocol):
    """A transport to one camera."""

    stats: LinkStats

    async def open(self) -> None:
        """Open the socket (and, on UDP, reset the camera's sequence numbers)."""
        ...

    async def close(self) -> None:
        """Close the socket; pending requests fail with LinkTimeout."""
        ...

    async def request(
        self, packet: bytes, *, inquiry: bool = False, completion: bool = False,
        timeout_s: float = 0.1, retries: int = 5, completion_timeout_s: float = 30.0,
    ) -> vp.Reply:
        """Send ``packet``; return the inquiry's answer, or the command's ACK (its Completion
        when ``completion``, waited for up to ``completion_timeout_s``). ViscaError on an error
        reply, LinkTimeout without an answer."""
        ...

    async def reset_sequence(self, timeout_s: float = 0.2, retries: int = 5) -> None:
        """Restart the sequence numbers (UDP; nothing on TCP)."""
        ...


def _raise_if_error(reply: vp.Reply, packet: bytes) -> vp.Reply:
    if reply.kind == "error":
        raise ViscaError(f"camera refused {packet.hex(' ')}: {reply.describe()}", reply.error)
    return reply


@dataclass(slots=True)
class _Pending:
    packet: bytes
    first: asyncio.Future[vp.Reply]
    done: asyncio.Future[vp.Reply] | None  # the Completion, when the caller waits for it
    sent_at: float = 0.0


class UdpLink(asyncio.DatagramProtocol):
    """Sony VISCA over IP on UDP (see the module docstring)."""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.stats = LinkStats()
        self._transport: asyncio.DatagramTransport | None = None
        self._seq = 0
        self._pending: dict[int, _Pending] = {}
        self._control: dict[int, asyncio.Future[bytes]] = {}
        self._reset_lock = asyncio.Lock()

    # -- asyncio.DatagramProtocol -----------------------------------------------------------
    def datagram_received(self, data: bytes, addr: tuple[str | int, ...]) -> None:
        try:
            msg = vp.unpack_message(data)
        except DataError:
            self.stats.errors += 1
            return
        if msg.payload_type == vp.PT_CONTROL_REPLY:
            fut = self._control.pop(msg.sequence, None)
            if fut is not None and not fut.done():
                fut.set_result(msg.payload)
            elif msg.payload == vp.CONTROL_ERR_SEQUENCE:
                pending = self._pending.get(msg.sequence)
                if pending is not None and not pending.first.done():
                    pending.first.set_exception(_SequenceRejected())
                elif pending is not None and pending.done is not None and not pending.done.done():
                    # The ACK came: the camera ran the command and no longer knows its number.
                    pending.done.set_exception(_CompletionForgotten())
            return
        if msg.payload_type != vp.PT_REPLY:
            return
        pending = self._pending.get(msg.sequence)
        if pending is None:
            return  # a late answer to a request already given up on or answered
        try:
            reply = vp.decode_reply(msg.payload)
        except DataError:
            self.stats.errors += 1
            return
        if not pending.first.done():
            self.stats.rtt_s.append(time.monotonic() - pending.sent_at)
            pending.first.set_result(reply)
        if pending.done is not None and not pending.done.done() and reply.kind != "ack":
            pending.done.set_result(reply)

    def error_received(self, exc: Exception) -> None:  # ICMP "port unreachable" and the like
        self.stats.errors += 1

    # -- ViscaLink --------------------------------------------------------------------------
    async def open(self) -> None:
        if self._transport is None:
            loop = asyncio.get_running_loop()
            transport, _ = await loop.create_datagram_endpoint(
                lambda: self, remote_addr=(self.host, self.port))
            self._transport = transport
        await self.reset_sequence()

    async def close(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None
        for p in list(self._pending.values()):
            for fut in (p.first, p.done):
                if fut is not None and not fut.done():
                    fut.set_exception(LinkTimeout("link closed"))
        self._pending.clear()

    def _send(self, ptype: int, seq: int, payload: bytes) -> None:
        if self._transport is None:
            raise LinkTimeout(f"VISCA link to {self.host}:{self.port} is not open")
        self._transport.sendto(vp.pack_message(ptype, seq, payload))
        self.stats.sent += 1

    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) % vp.SEQUENCE_MODULO
        return self._seq

    async def reset_sequence(self, timeout_s: float = 0.2, retries: int = 5) -> None:
        async with self._reset_lock:
            loop = asyncio.get_running_loop()
            for _ in range(retries + 1):
                fut: asyncio.Future[bytes] = loop.create_future()
                self._control[0] = fut
                self._send(vp.PT_CONTROL, 0, vp.CONTROL_RESET)
                try:
                    await asyncio.wait_for(fut, timeout_s)
                except TimeoutError:
                    self.stats.retransmits += 1
                    continue
                finally:
                    self._control.pop(0, None)
                self._seq = 0
                self.stats.sequence_resets += 1
                return
            self.stats.timeouts += 1
            raise LinkTimeout(f"no answer to RESET from {self.host}:{self.port} after {retries + 1} tries")

    async def request(
        self, packet: bytes, *, inquiry: bool = False, completion: bool = False,
        timeout_s: float = 0.1, retries: int = 5, completion_timeout_s: float = 30.0,
    ) -> vp.Reply:
        loop = asyncio.get_running_loop()
        ptype = vp.PT_INQUIRY if inquiry else vp.PT_COMMAND
        sequence_tries = 2
        deadline = time.monotonic() + completion_timeout_s  # for the Completion, over every renewal
        while True:
            seq = self._next_seq()
            pending = _Pending(packet, loop.create_future(), loop.create_future() if completion else None)
            self._pending[seq] = pending
            try:
                reply = await self._send_until_answered(ptype, seq, pending, timeout_s, retries)
                if pending.done is None or reply.kind != "ack":
                    return _raise_if_error(reply, packet)
                done = await self._await_completion(ptype, seq, pending, deadline, completion_timeout_s)
                return _raise_if_error(done, packet)
            except _CompletionForgotten:
                self.stats.completion_renewals += 1  # send it again under a new number
            except _SequenceRejected:
                sequence_tries -= 1
                if sequence_tries < 0:
                    raise LinkTimeout(
                        f"camera keeps rejecting sequence numbers for {packet.hex(' ')}") from None
                await self.reset_sequence()
            finally:
                self._pending.pop(seq, None)

    async def _send_until_answered(
        self, ptype: int, seq: int, pending: _Pending, timeout_s: float, retries: int
    ) -> vp.Reply:
        for attempt in range(retries + 1):
            if attempt:
                self.stats.retransmits += 1
            pending.sent_at = time.monotonic()
            self._send(ptype, seq, pending.packet)
            try:
                return await asyncio.wait_for(asyncio.shield(pending.first), timeout_s)
            except TimeoutError:
                continue
        self.stats.timeouts += 1
        pending.first.cancel()
        raise LinkTimeout(
            f"no answer from {self.host}:{self.port} to {pending.packet.hex(' ')} after {retries + 1} tries"
        )


    async def _await_completion(
        self, ptype: int, seq: int, pending: _Pending, deadline: float, completion_timeout_s: float
    ) -> vp.Reply:
        """Wait for the Completion until ``deadline`` (monotonic); every 0.5 s without it, ask
        again with the same number (a camera that still knows the number replays a lost
        Completion and does not restart a motion it already runs; one that does not answers
        "abnormal sequence number", raised here as _CompletionForgotten)."""
        assert pending.done is not None
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                self.stats.timeouts += 1
                raise LinkTimeout(f"no completion from {self.host}:{self.port} for {pending.packet.hex(' ')} "
                                  f"within {completion_timeout_s:g} s")
            try:
                return await asyncio.wait_for(asyncio.shield(pending.done), min(0.5, left))
            except TimeoutError:
                self.stats.retransmits += 1
                self._send(ptype, seq, pending.packet)


class _SequenceRejected(Exception):
    """The camera answered 'abnormal sequence number' (internal: the link resets and retries)."""


class _CompletionForgotten(Exception):
    """The camera answered 'abnormal sequence number' to a re-ask for a Completion after its ACK
    (internal: the link sends the command again under a new number)."""


class TcpLink:
    """Raw VISCA over TCP (see the module docstring)."""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.stats = LinkStats()
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._rx: asyncio.Task[None] | None = None
        self._lock = asyncio.Lock()
        self._first: asyncio.Future[vp.Reply] | None = None
        self._sockets: dict[int, asyncio.Future[vp.Reply]] = {}

    async def open(self) -> None:
        if self._writer is not None:
            return
        try:
            self._reader, self._writer = await asyncio.wait_for(
                asyncio.open_connection(self.host, self.port), 2.0)
        except (OSError, TimeoutError) as exc:
            raise LinkTimeout(f"cannot connect to {self.host}:{self.port}: {exc}") from None
        self._rx = asyncio.create_task(self._receive(), name=f"visca-tcp-{self.host}:{self.port}")

    async def close(self) -> None:
        if self._rx is not None:
            self._rx.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._rx
            self._rx = None
        if self._writer is not None:
            self._writer.close()
            with contextlib.suppress(Exception):
                await self._writer.wait_closed()
        self._reader = self._writer = None
        self._fail_all(LinkTimeout("link closed"))

    def _fail_all(self, exc: Exception) -> None:
        for fut in [self._first, *self._sockets.values()]:
            if fut is not None and not fut.done():
                fut.set_exception(exc)
        self._sockets.clear()

    async def _receive(self) -> None:
        assert self._reader is not None
        buffer = b""
        while True:
            chunk = await self._reader.read(256)
            if not chunk:
                self._fail_all(LinkTimeout(f"{self.host}:{self.port} closed the connection"))
                self._writer = None
                return
            packets, buffer = vp.split_packets(buffer + chunk)
            for packet in packets:
                try:
                    reply = vp.decode_reply(packet)
                except DataError:
                    self.stats.errors += 1
                    continue
                self._route(reply)

    def _route(self, reply: vp.Reply) -> None:
        if reply.kind == "ack" and reply.socket:
            # Registered here, before the requester resumes: the Completion may be next in line.
            self._sockets[reply.socket] = asyncio.get_running_loop().create_future()
        waiting = self._sockets.get(reply.socket) if reply.kind != "ack" and reply.socket else None
        if waiting is not None and not waiting.done():
            waiting.set_result(reply)
            del self._sockets[reply.socket]
        elif self._first is not None and not self._first.done():
            self._first.set_result(reply)

    async def reset_sequence(self, timeout_s: float = 0.2, retries: int = 5) -> None:
        return None

    async def request(
        self, packet: bytes, *, inquiry: bool = False, completion: bool = False,
        timeout_s: float = 0.1, retries: int = 5, completion_timeout_s: float = 30.0,
    ) -> vp.Reply:
        loop = asyncio.get_running_loop()
        # No retransmission on TCP; the time-out covers what the retries would have.
        wait_s = timeout_s * (retries + 1)
        async with self._lock:
            if self._writer is None:
                raise LinkTimeout(f"VISCA link to {self.host}:{self.port} is not open")
            self._first = loop.create_future()
            sent_at = time.monotonic()
            self._writer.write(packet)
            self.stats.sent += 1
            try:
                reply = await asyncio.wait_for(self._first, wait_s)
            except TimeoutError:
                self.stats.timeouts += 1
                raise LinkTimeout(f"no answer from {self.host}:{self.port} to {packet.hex(' ')}") from None
            self.stats.rtt_s.append(time.monotonic() - sent_at)
            done = self._sockets.get(reply.socket) if completion and reply.kind == "ack" else None
        _raise_if_error(reply, packet)
        if done is None:
            return reply
        try:
            return _raise_if_error(await asyncio.wait_for(done, completion_timeout_s), packet)
        except TimeoutError:
            self.stats.timeouts += 1
            raise LinkTimeout(f"no completion from {self.host}:{self.port} for {packet.hex(' ')}") from None


def open_link(transport: str, host: str, port: int) -> ViscaLink:
    """The link for a driver spec's transport ("udp" or "tcp")."""
    if transport == "udp":
        return UdpLink(host, port)
    if transport == "tcp":
        return TcpLink(host, port)
    raise DriverFault(f"unknown VISCA transport {transport!r}")
