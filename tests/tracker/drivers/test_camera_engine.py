"""The engine steering a PTZ camera (the emulator) by targets: it holds where the camera is at
start, follows a pointing command, jogs, and a lost link becomes the engine's fault mode."""

from __future__ import annotations

import asyncio
import math
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tracker.drivers.camera_emulator import CameraEmulator
from tracker.drivers.camera_profiles import get_profile
from tracker.drivers.spec import parse_driver_url
from tracker.drivers.visca import ViscaCamera
from tracker.engine import Engine

DEG = math.radians(1.0)
LIMITS = {"pan": (-90 * DEG, 90 * DEG), "tilt": (-45 * DEG, 45 * DEG)}
ROOT = Path(__file__).resolve().parents[3]


async def until(cond: Callable[[], object], timeout_s: float, what: str) -> None:
    end = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > end:
            pytest.fail(f"{what} not reached within {timeout_s} s")
        await asyncio.sleep(0.01)


async def test_engine_holds_then_follows_pointing_and_jog_on_a_camera() -> None:
    emu = CameraEmulator("sony_srg", latency_s=0.03, seed=3)
    emu.twin.axes["pan"].motor_rad = 10 * DEG  # VISCA right: the console's -10 deg
    port = await emu.start()
    cam = ViscaCamera(parse_driver_url(f"visca+udp://127.0.0.1:{port}"), get_profile("sony_srg"), LIMITS)
    engine = Engine(cam)
    task = asyncio.create_task(engine.run(realtime=True))
    try:
        await until(lambda: cam.enabled, 5.0, "enabled once ready")
        assert engine.mode == "hold"
        assert engine.status().pan_target_rad == pytest.approx(-10 * DEG, abs=0.1 * DEG)
        assert emu.responder_stats.motion_commands == 0  # holding where it is: nothing sent

        engine.point(30 * DEG, -8 * DEG)
        await until(lambda: abs(-emu.twin.axes["pan"].motor_rad - 30 * DEG) < 0.15 * DEG
                    and abs(emu.twin.axes["tilt"].motor_rad + 8 * DEG) < 0.15 * DEG
                    and emu.twin.axes["pan"].speed_rad_s == 0.0, 5.0, "pointing target")
        await until(lambda: abs(engine.status().pan_rad - 30 * DEG) < 0.15 * DEG, 1.0, "reported angle")
        assert cam.describe()["achieved_rate_hz"] == pytest.approx(25.0, rel=0.2)

        engine.jog("pan", -20 * DEG, timeout_s=0.5)
        await until(lambda: engine.status().pan_rad < 25 * DEG, 3.0, "jog")
        await until(lambda: emu.twin.axes["pan"].speed_rad_s == 0.0 and not engine._jog, 3.0, "jog auto-stop")

        await emu.close()
        await until(lambda: engine.mode == "fault", 3.0, "fault mode")
        assert any("link lost" in f for f in engine.status().faults)
    finally:
        engine.stop()
        await task
        await cam.close()
        await emu.close()


def test_camera_emulator_command_serves_until_its_duration() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "tracker", "camera-emulator", "--port", "0", "--profile", "ptzoptics",
         "--loss", "0.1", "--latency-ms", "30", "--duration-s", "1.2", "--no-limits"],
        capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert "camera emulator (ptzoptics) on visca+udp://127.0.0.1:" in proc.stdout
    assert "loss 0.1, latency 30 ms, Pan-tiltLimitSet refused" in proc.stdout
    assert "range pan -170.0..170.0° tilt -30.0..90.0°" in proc.stdout  # the status line, each second
