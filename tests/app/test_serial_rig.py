"""The service on a DC rig behind its serial motor controller: driver = "serial://PTY" against
the emulator; status names the board and shows the loop's timing, pointing moves the rig, a
lost board is a fault that only an engineer clears, once the board is back."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.main import create_app
from app.settings import load_settings
from tracker.drivers.motor_board import MotorBoard
from tracker.drivers.motor_emulator import MotorEmulator

from .conftest import free_port, poll

API = "/api/v1"


def test_service_steers_the_serial_rig_and_recovers_from_a_lost_board(
        tmp_path: Path, board: MotorEmulator) -> None:
    settings = load_settings(None, data_dir=str(tmp_path / "data"), viewer_enabled=False,
                             viewer_port=free_port(), audio_enabled=False,
                             driver=f"serial://{board.path}?baud=1000000&rate=250")
    with TestClient(create_app(settings)) as client:
        h = {"X-API-Key": (tmp_path / "data" / "admin.key").read_text().strip()}

        def status() -> dict[str, Any]:
            r = client.get(f"{API}/status", headers=h)
            assert r.status_code == 200, r.text
            body: dict[str, Any] = r.json()
            return body

        s = poll(lambda: (st := status())["mode"] == "hold" and st, 15.0)
        assert s, f"rig not enabled: {status()}"
        assert s["driver"]["kind"] == "serial" and s["driver"]["state"] == "connected"
        assert "3dat-mc-emu" in s["driver"]["board"] and s["driver"]["rate_hz"] == 250
        assert s["loop"]["in_thread"] and s["loop"]["period_ms"] == pytest.approx(8.0)

        r = client.put(f"{API}/pointing", headers=h, json={"pan_deg": 20.0, "tilt_deg": -5.0})
        assert r.status_code == 200, r.text
        twin = board.board.twin
        arrived = poll(lambda: abs(math.degrees(twin.load_rad("pan")) - 20.0) < 0.3
                       and abs(math.degrees(twin.load_rad("tilt")) + 5.0) < 0.3, 15.0)
        assert arrived, f"rig at {math.degrees(twin.load_rad('pan')):.2f}°, status {status()}"
        assert status()["loop"]["ticks"] > 0

        board.close()
        s = poll(lambda: (st := status())["mode"] == "fault" and st, 10.0)
        assert s and "link lost" in s["faults"][0]
        r = client.post(f"{API}/faults/clear", headers=h)
        assert r.status_code == 503, r.text  # the board is still gone
        restarted = MotorEmulator(MotorBoard(twin), pty_link=board.pty_link)
        restarted.start()
        try:
            assert poll(lambda: status()["driver"]["state"] == "connected", 15.0)
            # Nothing moves by itself: the refused clear left the rig disabled.
            assert status()["mode"] == "disabled" and not restarted.board.armed
            r = client.post(f"{API}/faults/clear", headers=h)
            assert r.status_code == 200, r.text
            assert r.json()["mode"] in ("manual", "hold")
            assert poll(lambda: restarted.board.armed, 10.0)
        finally:
            restarted.close()
