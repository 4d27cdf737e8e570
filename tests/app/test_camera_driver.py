"""The service on a PTZ camera: driver = "visca+udp://127.0.0.1:PORT" against the emulator
(running in its own thread and event loop), status names the driver, pointing moves the camera;
bad driver settings stop the start naming the setting."""

from __future__ import annotations

import asyncio
import math
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.main import create_app
from app.settings import load_settings
from tracker.drivers.camera_emulator import CameraEmulator
from tracker.errors import ConfigError

from .conftest import free_port, poll

API = "/api/v1"


class EmulatorThread:
    """A camera emulator on its own event loop in a daemon thread."""

    def __init__(self, **options: object) -> None:
        self.loop = asyncio.new_event_loop()
        self.emulator = CameraEmulator("generic", **options)  # type: ignore[arg-type]
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        self.port = asyncio.run_coroutine_threadsafe(self.emulator.start(), self.loop).result(5)

    def pan_deg(self) -> float:
        return -math.degrees(self.emulator.twin.axes["pan"].motor_rad)

    def tilt_deg(self) -> float:
        return math.degrees(self.emulator.twin.axes["tilt"].motor_rad)

    def close(self) -> None:
        asyncio.run_coroutine_threadsafe(self.emulator.close(), self.loop).result(5)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)


@pytest.fixture
def camera() -> Iterator[EmulatorThread]:
    emu = EmulatorThread(latency_s=0.02, seed=5)
    yield emu
    emu.close()


def test_service_reports_the_camera_and_follows_pointing(tmp_path: Path, camera: EmulatorThread) -> None:
    settings = load_settings(None, data_dir=str(tmp_path), viewer_enabled=False, viewer_port=free_port(),
                             audio_enabled=False, driver=f"visca+udp://127.0.0.1:{camera.port}")
    app = create_app(settings)
    with TestClient(app) as client:
        key = (tmp_path / "admin.key").read_text().strip()
        h = {"X-API-Key": key}

        def status() -> dict:  # type: ignore[type-arg]
            r = client.get(f"{API}/status", headers=h)
            assert r.status_code == 200, r.text
            body: dict = r.json()  # type: ignore[type-arg]
            return body

        s = poll(lambda: (st := status())["driver"]["state"] == "connected"
                 and st["mode"] == "hold" and st, 5.0)
        assert s, f"camera not connected: {status()}"
        d = s["driver"]
        assert d["kind"] == "visca" and d["url"] == f"visca+udp://127.0.0.1:{camera.port}"
        assert d["profile"] == "generic" and d["command_rate_hz"] == 25.0
        # the guard lines are the camera's own limits too (inside the ±90°/±45° soft limits)
        assert d["camera_limits"]["state"] == "set" and d["camera_limits"]["guard"] == "camera and host"
        assert -90.0 < d["camera_limits"]["pan_deg"][0] < d["camera_limits"]["pan_deg"][1] < 90.0

        r = client.put(f"{API}/pointing", headers=h, json={"pan_deg": 25.0, "tilt_deg": -8.0})
        assert r.status_code == 200, r.text
        arrived = poll(lambda: abs(camera.pan_deg() - 25.0) < 0.2 and abs(camera.tilt_deg() + 8.0) < 0.2, 6.0)
        assert arrived, f"camera at {camera.pan_deg():.2f}/{camera.tilt_deg():.2f}, status {status()}"
        s = poll(lambda: (st := status()) and abs(st["pan_deg"] - 25.0) < 0.2
                 and abs(st["tilt_deg"] + 8.0) < 0.2 and st, 2.0)
        assert s, f"status does not report the camera's angles: {status()}"
        assert s["driver"]["rtt_ms_median"] is not None and s["driver"]["rtt_ms_median"] >= 20.0


@pytest.mark.parametrize(
    ("overrides", "match"),
    [
        ({"driver": "visca+udp://cam:99999"}, "setting 'driver'"),
        ({"driver": "modbus:///dev/ttyUSB0"}, "unknown scheme"),
        ({"camera_profile": "nikon"}, "setting 'camera_profile'.*unknown camera profile"),
        ({"camera_rate_hz": 500}, "setting 'camera_rate_hz'"),
    ],
    ids=["port", "scheme", "profile", "rate"],
)
def test_bad_driver_settings_name_the_setting(tmp_path: Path, overrides: dict, match: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ConfigError, match=match):
        load_settings(None, data_dir=str(tmp_path), **overrides)


def test_driver_comes_from_the_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TRACKER_DRIVER", "visca+tcp://ptz.local:5678")
    assert load_settings(None, data_dir=str(tmp_path)).driver == "visca+tcp://ptz.local:5678"
    assert load_settings(None, data_dir=str(tmp_path), driver="SIM").driver == "sim"
