"""Back-off for client addresses that keep sending bad API keys: 429 with Retry-After, doubling.

An address may send ``limit`` unknown or revoked keys within ``window_s``; the next one starts a
block of ``FIRST_BLOCK_S`` during which every bad key from it gets 429 (the key is not looked
at twice: the block only answers sooner). Each further block while the bad keys go on lasts twice
as long, up to ``max_block_s``; a quiet ``max_block_s`` starts the doubling again. A *valid*
key from a blocked address still works: keys are 256-bit random, so the block is about load and
noise, not guessing, and a room controller behind the same NAT as a misbehaving tab keeps
working. A missing key is not counted (nothing is being guessed).
"""

from __future__ import annotations

import time
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, field

FIRST_BLOCK_S = 5.0
MAX_ADDRESSES = 10_000  # the oldest entries are forgotten first


@dataclass(slots=True)
class _Address:
    failures_s: deque[float] = field(default_factory=deque)
    strikes: int = 0
    blocked_until_s: float = float("-inf")


class BadKeyBackoff:
    """Counts bad keys per client address and says how long it must wait."""

    def __init__(
        self,
        limit: int = 10,
        window_s: float = 60.0,
        max_block_s: float = 600.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.limit, self.window_s, self.max_block_s = limit, window_s, max_block_s
        self._clock = clock
        self._addresses: OrderedDict[str, _Address] = OrderedDict()

    def retry_after_s(self, address: str) -> float:
        """Seconds ``address`` must still wait (0 when it is not blocked)."""
        a = self._addresses.get(address)
        return 0.0 if a is None else max(0.0, a.blocked_until_s - self._clock())

    def failed(self, address: str) -> float:
        """Count one bad key from ``address``; the seconds it must now wait (0: answer 401)."""
        now = self._clock()
        a = self._addresses.pop(address, None) or _Address()
        self._addresses[address] = a  # most recent last
        while len(self._addresses) > MAX_ADDRESSES:
            self._addresses.popitem(last=False)
        if a.blocked_until_s > now:
            return a.blocked_until_s - now
        while a.failures_s and a.failures_s[0] <= now - self.window_s:
            a.failures_s.popleft()
        a.failures_s.append(now)
        if len(a.failures_s) <= self.limit:
            return 0.0
        if now - a.blocked_until_s > self.max_block_s:
            a.strikes = 0  # quiet long enough: the doubling starts again
        a.strikes += 1
        a.blocked_until_s = now + min(self.max_block_s, FIRST_BLOCK_S * 2.0 ** (a.strikes - 1))
        a.failures_s.clear()
        return a.blocked_until_s - now
