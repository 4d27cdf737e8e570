"""Figures of the VISCA driver against the camera emulator on 127.0.0.1: command rate achieved,
round trips, a 30° step through the speed servo and one-shot commands under packet loss.

    python bench/bench_camera.py
"""

from __future__ import annotations

import asyncio
import math
import time

from tracker.drivers.camera_emulator import CameraEmulator
from tracker.drivers.camera_profiles import get_profile
from tracker.drivers.spec import parse_driver_url
from tracker.drivers.visca import ViscaCamera

DEG = math.radians(1.0)
LIMITS = {"pan": (-90 * DEG, 90 * DEG), "tilt": (-45 * DEG, 45 * DEG)}


async def run(loss: float, latency_s: float) -> str:
    emu = CameraEmulator("generic", loss=loss, latency_s=latency_s, seed=11)
    port = await emu.start()
    url = parse_driver_url(f"visca+udp://127.0.0.1:{port}")
    cam = ViscaCamera(url, get_profile(), LIMITS, link_lost_s=3.0)
    cam.start()
    while not cam.ready:
        await asyncio.sleep(0.01)
    cam.enable()
    t0 = time.monotonic()
    cam.set_target("pan", 30 * DEG)
    cam.set_target("tilt", 0.0)
    overshoot = 0.0
    while True:
        pan = -emu.twin.axes["pan"].motor_rad
        overshoot = max(overshoot, pan - 30 * DEG)
        if abs(pan - 30 * DEG) < 0.1 * DEG and emu.twin.axes["pan"].speed_rad_s == 0.0:
            break
        await asyncio.sleep(0.005)
    step_s = time.monotonic() - t0
    ok = 0
    t1 = time.monotonic()
    for k in range(20):
        await cam.preset_set(k)
        ok += 1
    one_shot_ms = (time.monotonic() - t1) / 20 * 1e3
    d = cam.describe()
    await cam.close()
    await emu.close()
    return (f"| {loss:.0%} | {latency_s * 1e3:.0f} ms | {d['achieved_rate_hz']} Hz | "
            f"{d['rtt_ms_median']} / {d['rtt_ms_p95']} ms | {step_s:.2f} s | {overshoot / DEG:.2f}° | "
            f"{ok}/20, {one_shot_ms:.0f} ms | {d['retransmits']} |")


async def main() -> None:
    print("| loss | latency | command rate | RTT median / p95 | 30° step to 0.1° | overshoot | "
          "one-shot commands (mean time) | retransmits |")
    print("|---|---|---|---|---|---|---|---|")
    for loss, latency in ((0.0, 0.0), (0.0, 0.03), (0.1, 0.03), (0.2, 0.03)):
        print(await run(loss, latency), flush=True)


if __name__ == "__main__":
    asyncio.run(main())
