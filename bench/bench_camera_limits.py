"""How far past a soft limit the emulated head runs when the host stalls mid-drive.

The real VISCA driver (its command cycle on a loop thread of its own, as in the service) drives
one axis at full speed toward a soft limit of the emulator's head, over UDP on 127.0.0.1 with
a round trip of ``--latency-ms``. When the head comes within a trigger distance of the limit,
the driver's loop thread is frozen for N command periods (the host stalls: a swap storm, a
debugger, a GC pause), or for good (N = inf: the host died in the middle of a speed drive).
The figure is the worst excursion of the head (the twin's motor angle) past the soft limit,
over trigger distances from 0.5 to 32 degrees (``--triggers``) and both limits of each axis.

    python bench/bench_camera_limits.py [--profiles generic,ptzoptics] [--latency-ms 20]
        [--stalls 1,2,5,inf] [--no-camera-limits]

Run it with ``PYTHONPATH=<checkout>`` to measure another checkout's driver (it prints which).
"""

from __future__ import annotations

import argparse
import asyncio
import math
import threading
import time
from collections.abc import Callable

import tracker
from tracker.drivers.camera_emulator import CameraEmulator
from tracker.drivers.camera_profiles import CameraProfile, get_profile, profile_names
from tracker.drivers.camera_twin import CameraTwin
from tracker.drivers.spec import parse_driver_url
from tracker.drivers.visca import ViscaCamera
from tracker.errors import DriverFault

DEG = math.radians(1.0)
LIMITS = {"pan": (-90 * DEG, 90 * DEG), "tilt": (-15 * DEG, 45 * DEG)}
TRIGGERS_DEG = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
RATE_HZ = 25.0


async def until(cond: Callable[[], object], timeout_s: float, what: str) -> None:
    end = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > end:
            raise TimeoutError(what)
        await asyncio.sleep(0.005)


class WatchedTwin(CameraTwin):
    """The emulator's twin, calling ``watch()`` after every step (where the excursion is read)."""

    def __init__(self, profile: CameraProfile) -> None:
        super().__init__(profile)
        self.watch: Callable[[], None] | None = None

    def step(self, dt_s: float) -> tuple[bool, bool]:
        out = super().step(dt_s)
        if self.watch is not None:
            self.watch()
        return out


class Rig:
    """One emulator and one driver, reused run after run."""

    def __init__(self, profile: str, latency_s: float, camera_limits: bool) -> None:
        self.profile = get_profile(profile)
        self.twin = WatchedTwin(self.profile)
        refuse: dict[str, bool] = {} if camera_limits else {"limit_commands": False}
        self.emu = CameraEmulator(profile, latency_s=latency_s, seed=3, twin=self.twin, **refuse)
        self.cam: ViscaCamera | None = None

    async def start(self) -> None:
        port = await self.emu.start()
        self.cam = ViscaCamera(parse_driver_url(f"visca+udp://127.0.0.1:{port}"), self.profile, LIMITS,
                               rate_hz=RATE_HZ, own_thread=True)
        self.cam.start()
        await until(lambda: self.cam is not None and self.cam.ready, 10.0, "connection")

    def console(self, axis: str) -> float:
        return self.profile.sign[axis] * self.emu.twin.axes[axis].motor_rad

    async def ready_at(self, axis: str, start_rad: float) -> ViscaCamera:
        cam = self.cam
        assert cam is not None
        cam.disable()
        await until(lambda: all(ax.speed_rad_s == 0.0 for ax in self.emu.twin.axes.values()), 10.0, "rest")
        await asyncio.sleep(0.1)  # a link lost during a long stall latches its fault now
        for ax_name, ax in self.emu.twin.axes.items():
            x = self.profile.sign[ax_name] * (start_rad if ax_name == axis else 0.0)
            ax.motor_rad = ax.load_rad = x
            ax.speed_rad_s, ax.mode, ax.drive_rad_s = 0.0, "idle", 0.0
        end = time.monotonic() + 20.0
        while True:
            await until(lambda: cam.ready and abs(cam.read_encoder(axis) - start_rad) < 0.2 * DEG, 20.0,
                        "position")
            await asyncio.sleep(3 / RATE_HZ)
            cam.clear_faults()
            try:
                cam.enable()
                break
            except DriverFault:
                if time.monotonic() > end:
                    raise
        return cam

    async def run(self, axis: str, side: int, stall: int | None, trigger_rad: float) -> float:
        """Worst excursion past the soft limit (rad, > 0 past it) of one drive with one stall."""
        lo, hi = LIMITS[axis]
        limit = hi if side > 0 else lo
        v = self.profile.max_speed_rad_s(axis)
        run_up = trigger_rad + v * v / (2 * self.profile.accel_rad_s2) + 5 * DEG
        start = limit - side * run_up
        start = max(min(start, hi - 1 * DEG), lo + 1 * DEG)
        cam = await self.ready_at(axis, start)
        release = threading.Event()
        state = {"worst": -math.inf, "frozen_at": None}

        def watch() -> None:
            past = side * (self.console(axis) - limit)
            state["worst"] = max(state["worst"], past)  # type: ignore[type-var]
            if state["frozen_at"] is None and -past <= trigger_rad:
                state["frozen_at"] = time.monotonic()
                lt = cam._loop_thread
                assert lt is not None
                period = 1.0 / RATE_HZ
                lt.loop.call_soon_threadsafe(release.wait, 60.0 if stall is None else stall * period)

        self.twin.watch = watch
        cam.set_rate(axis, side * v)
        try:
            await until(lambda: state["frozen_at"] is not None, 20.0, "trigger")
            if stall is not None:
                await asyncio.sleep(stall / RATE_HZ + 0.05)
            rest_since = [time.monotonic()]

            def at_rest() -> bool:
                axes = self.emu.twin.axes.values()
                moving = any(ax.speed_rad_s != 0.0 or ax.mode == "position" for ax in axes)
                if moving:
                    rest_since[0] = time.monotonic()
                return time.monotonic() - rest_since[0] > 0.3

            await until(at_rest, 30.0, "head at rest")
        finally:
            self.twin.watch = None
            release.set()
        cam.disable()
        worst = state["worst"]
        assert isinstance(worst, float)
        return worst

    async def close(self) -> None:
        if self.cam is not None:
            await self.cam.close()
        await self.emu.close()


async def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profiles", default=",".join(profile_names()))
    parser.add_argument("--latency-ms", type=float, default=20.0)
    parser.add_argument("--stalls", default="1,2,5,inf")
    parser.add_argument("--triggers", default=",".join(f"{t:g}" for t in TRIGGERS_DEG),
                        help="distances (deg) before the limit at which the host stalls")
    parser.add_argument("--no-camera-limits", action="store_true",
                        help="the emulated camera answers Pan-tiltLimitSet with an error")
    args = parser.parse_args()
    stalls = [None if s == "inf" else int(s) for s in args.stalls.split(",")]
    print(f"tracker from {tracker.__file__}; round trip {args.latency_ms:g} ms, {RATE_HZ:g} Hz commands"
          + ("; the camera refuses LimitSet" if args.no_camera_limits else ""))
    print("| profile | " + " | ".join(f"stall {'∞' if s is None else s}" for s in stalls) + " |")
    print("|---|" + "---|" * len(stalls))
    for name in args.profiles.split(","):
        rig = Rig(name, args.latency_ms * 1e-3, not args.no_camera_limits)
        await rig.start()
        cells = []
        try:
            for stall in stalls:
                worst = -math.inf
                where = ""
                triggers = [float(t) for t in args.triggers.split(",")]
                if stall is None and not args.no_camera_limits:
                    triggers = [8.0]  # a dead host with the camera's limits: one trigger tells
                for axis in ("pan", "tilt"):
                    for side in (1, -1):
                        for trig in triggers:
                            past = await rig.run(axis, side, stall, trig * DEG)
                            if past > worst:
                                worst, where = past, f"{axis}{'+' if side > 0 else '-'} at {trig:g}°"
                cells.append(f"{max(worst, 0.0) / DEG:.3f}° ({where})" if worst > 0 else "none")
        finally:
            await rig.close()
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    asyncio.run(main())
