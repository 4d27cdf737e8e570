"""The speed-table identification on the twin (simulated clock) and through the VISCA driver
against the camera emulator over real UDP sockets, with a twin whose table departs from the
profile file's."""

from __future__ import annotations

import asyncio
import dataclasses
import json
import math
import time

import pytest

from tracker.cli import main
from tracker.drivers.camera_emulator import CameraEmulator
from tracker.drivers.camera_profiles import CameraProfile, get_profile
from tracker.drivers.camera_twin import CameraTwin
from tracker.drivers.spec import parse_driver_url
from tracker.drivers.visca import ViscaCamera
from tracker.errors import ConfigError
from tracker.workbench.camera.speed_id import TwinRig, ViscaRig, identify_speed_table

SLOWER = {14: 0.9}  # the hidden camera: step 14 is 10 % slower than the file says
FASTER_NEG = 1.06  # and every step is 6 % faster toward negative angles


def hidden_profile(base: CameraProfile) -> tuple[CameraProfile, dict[int, float]]:
    """A twin profile whose pan table departs from ``base``'s (returns the true speeds)."""
    pan = tuple(v * SLOWER.get(i + 1, 1.0) for i, v in enumerate(base.speeds_rad_s["pan"]))
    return dataclasses.replace(base, speeds_rad_s={**base.speeds_rad_s, "pan": pan}), dict(enumerate(pan, 1))


def test_twin_identification_finds_the_departing_step() -> None:
    prof = get_profile("generic")
    hidden, true = hidden_profile(prof)
    rig = TwinRig(CameraTwin(hidden), file_profile=prof, latency_s=0.06)
    res = asyncio.run(identify_speed_table(rig, "pan", count=24))
    measured = {(r.step, r.direction): r for r in res.runs}
    assert len(measured) >= 44  # the fastest steps may lack room between the limits
    for (step, _), r in measured.items():
        assert r.rate_rad_s == pytest.approx(true[step], rel=0.02)
    assert measured[(14, 1)].deviation_percent == pytest.approx(-10.0, abs=1.5)
    assert abs(measured[(13, 1)].deviation_percent) < 2.0
    assert "step 14" in res.notes[-1]
    assert res.params()["speed_table.positive.14"] == measured[(14, 1)].rate_rad_s


def test_unknown_step_and_axis_are_refused() -> None:
    rig = TwinRig(CameraTwin(get_profile("generic")))
    with pytest.raises(ConfigError, match="outside the generic profile's pan table 1..24"):
        asyncio.run(identify_speed_table(rig, "pan", steps=(0, 3)))
    with pytest.raises(ConfigError, match="unknown axis"):
        asyncio.run(identify_speed_table(rig, "roll"))


async def test_visca_driver_against_the_emulator_over_udp() -> None:
    prof = get_profile("generic")
    hidden, true = hidden_profile(prof)
    emu = CameraEmulator(prof, latency_s=0.02, seed=3, twin=CameraTwin(hidden))
    port = await emu.start()
    cam = ViscaCamera(parse_driver_url(f"visca+udp://127.0.0.1:{port}"), prof, rate_hz=40.0)
    try:
        cam.start()
        end = time.monotonic() + 5.0
        while not cam.ready:
            assert time.monotonic() < end, "no connection to the emulator"
            await asyncio.sleep(0.01)
        cam.enable()
        res = await identify_speed_table(ViscaRig(cam), "pan", steps=(14, 20))
    finally:
        await cam.close()
        await emu.close()
    measured = {(r.step, r.direction): r for r in res.runs}
    assert set(measured) == {(14, 1), (14, -1), (20, 1), (20, -1)}
    for (step, _), r in measured.items():
        assert r.rate_rad_s == pytest.approx(true[step], rel=0.03)
    assert measured[(14, -1)].deviation_percent == pytest.approx(-10.0, abs=2.5)
    assert abs(measured[(20, 1)].deviation_percent) < 2.5
    assert emu.stats.received > 50  # it went through the sockets


def test_cli_speed_id_on_the_twin(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["camera", "speed-id", "--profile", "sony_srg", "--steps", "3,10", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["profile"] == "sony_srg" and len(out["runs"]) == 4
    assert out["max_deviation_percent"] < 2.0
    assert main(["camera", "speed-id", "--steps", "x"]) == 2
    assert "--steps 'x'" in capsys.readouterr().err
    assert math.isfinite(out["elapsed_s"])
