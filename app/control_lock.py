"""Manual control: any number of viewers, one holder of pointing/jog at a time; everyone sees who.

The holder is a key (its id and name). Holding lapses after ``ttl_s`` without a manual command,
so a closed browser tab does not lock the rig forever. An engineer or admin may take over.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from app.auth import Principal, Role
from app.errors import Conflict


@dataclass(frozen=True, slots=True)
class Holder:
    """Who holds manual control and since when (monotonic seconds)."""

    key_id: int
    name: str
    since_s: float
    last_active_s: float


class ControlLock:
    """One holder of manual control at a time."""

    def __init__(self, ttl_s: float = 30.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.ttl_s = ttl_s
        self._clock = clock
        self._holder: Holder | None = None

    def holder(self) -> Holder | None:
        """The current holder, or None (an idle holder has lapsed)."""
        h = self._holder
        if h is not None and self._clock() - h.last_active_s > self.ttl_s:
            self._holder = None
            return None
        return h

    def acquire(self, who: Principal, force: bool = False) -> Holder:
        """Take (or refresh) manual control; Conflict (409) when someone else holds it."""
        now = self._clock()
        h = self.holder()
        if h is not None and h.key_id != who.key_id:
            if not (force and who.role >= Role.engineer):
                raise Conflict(
                    f"manual control is held by {h.name!r}; wait for release or ask an engineer to take over",
                    holder=h.name,
                )
            h = None
        since = h.since_s if h is not None else now
        self._holder = Holder(who.key_id, who.name, since, now)
        return self._holder

    def release(self, who: Principal) -> bool:
        """Give up control; True when ``who`` held it (an engineer may release anyone's)."""
        h = self.holder()
        if h is None:
            return False
        if h.key_id != who.key_id and who.role < Role.engineer:
            raise Conflict(f"manual control is held by {h.name!r}, not by you", holder=h.name)
        self._holder = None
        return True

    def release_key(self, key_id: int) -> bool:
        """Free control if the key ``key_id`` holds it (the key was revoked); True when it did."""
        if self._holder is None or self._holder.key_id != key_id:
            return False
        self._holder = None
        return True

    def describe(self) -> dict[str, object] | None:
        """JSON view for status: holder name and seconds held."""
        h = self.holder()
        if h is None:
            return None
        return {"name": h.name, "held_s": round(self._clock() - h.since_s, 1)}
