"""A test double of tracker.engine.Engine (the contract in issue 2) for service-only tests.

It follows targets with a first-order lag at 1 kHz of simulated time; no physics. Used only
where a test is about the service (auth, locks, storage), never about the rig's behaviour.
"""

from __future__ import annotations

import asyncio
import math
from dataclasses import dataclass, replace

from tracker.control.gains import ObserverPdGains
from tracker.errors import ConfigError


@dataclass(frozen=True, slots=True)
class Snap:
    t_s: float
    pan_rad: float
    tilt_rad: float
    pan_target_rad: float
    tilt_target_rad: float
    pan_u_v: float
    tilt_u_v: float
    mode: str
    tracking: bool
    source: str | None
    estimate_azimuth_rad: float | None
    estimate_elevation_rad: float | None


@dataclass(frozen=True, slots=True)
class Status:
    t_s: float
    pan_rad: float
    tilt_rad: float
    pan_target_rad: float
    tilt_target_rad: float
    mode: str
    tracking: bool
    faults: tuple[str, ...]
    active_talker: str | None


class _Sub:
    def __init__(self, eng: FakeEngine, maxsize: int) -> None:
        self.q: asyncio.Queue[Snap] = asyncio.Queue(maxsize)
        self.eng = eng

    def __aiter__(self) -> _Sub:
        return self

    async def __anext__(self) -> Snap:
        return await self.q.get()

    def close(self) -> None:
        self.eng.subs.discard(self)


class FakeEngine:
    LIMITS = {"pan": math.radians(90), "tilt": math.radians(45)}

    def __init__(self, driver: object = None) -> None:
        self.t = 0.0
        self.angle = {"pan": 0.0, "tilt": 0.0}
        self.target = {"pan": 0.0, "tilt": 0.0}
        self.jogs: dict[str, tuple[float, float]] = {}
        self.tracking = False
        self.mode = "hold"
        self.subs: set[_Sub] = set()
        self._stop = False
        g = ObserverPdGains(
            kp_v_per_rad=40.0, kd_v_s_per_rad=1.2, ki_v_per_rad_s=20.0, observer_bandwidth_hz=60.0
        )
        self._gains = {"pan": g, "tilt": g}

    async def run(self, realtime: bool = True, duration_s: float | None = None) -> None:
        while not self._stop and (duration_s is None or self.t < duration_s):
            for _ in range(5):
                self.t += 0.001
                for ax in ("pan", "tilt"):
                    if ax in self.jogs:
                        rate, until = self.jogs[ax]
                        if self.t > until:
                            del self.jogs[ax]
                        else:
                            lim = self.LIMITS[ax] - 0.01
                            self.target[ax] = max(-lim, min(lim, self.target[ax] + rate * 0.001))
                    self.angle[ax] += (self.target[ax] - self.angle[ax]) * 0.01
                s = Snap(
                    self.t,
                    self.angle["pan"],
                    self.angle["tilt"],
                    self.target["pan"],
                    self.target["tilt"],
                    0.1,
                    0.0,
                    self.mode,
                    self.tracking,
                    None,
                    None,
                    None,
                )
                for sub in list(self.subs):
                    if not sub.q.full():
                        sub.q.put_nowait(s)
            await asyncio.sleep(0.005 if realtime else 0)

    def stop(self) -> None:
        self._stop = True

    def subscribe(self, maxsize: int = 256) -> _Sub:
        sub = _Sub(self, maxsize)
        self.subs.add(sub)
        return sub

    def status(self) -> Status:
        return Status(
            self.t,
            self.angle["pan"],
            self.angle["tilt"],
            self.target["pan"],
            self.target["tilt"],
            self.mode,
            self.tracking,
            (),
            None,
        )

    def set_tracking(self, on: bool) -> None:
        self.tracking = on
        self.mode = "tracking" if on else "hold"

    def set_target_source(self, source: object) -> None:
        pass

    def point(self, pan_rad: float, tilt_rad: float) -> None:
        for ax, v in (("pan", pan_rad), ("tilt", tilt_rad)):
            if abs(v) > self.LIMITS[ax]:
                raise ConfigError(f"{ax} target outside the soft limit ±{math.degrees(self.LIMITS[ax]):g}°")
        self.target = {"pan": pan_rad, "tilt": tilt_rad}
        self.mode = "manual"

    def release(self) -> None:
        self.mode = "tracking" if self.tracking else "hold"

    def jog(self, axis: str, rate_rad_s: float, timeout_s: float = 0.5) -> None:
        self.mode = "manual"
        if rate_rad_s == 0:
            self.jogs.pop(axis, None)
        else:
            self.jogs[axis] = (rate_rad_s, self.t + timeout_s)

    def gains(self, axis: str) -> ObserverPdGains:
        return self._gains[axis]

    def set_gains(self, axis: str, gains: ObserverPdGains) -> None:
        self._gains[axis] = replace(gains)
