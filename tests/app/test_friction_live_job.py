"""POST /api/v1/jobs/friction-id with source "live": the sweep on the service's own DC rig (a
serial motor controller, here the emulator on a pseudo-terminal), taken over while it runs."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.main import create_app
from app.settings import load_settings
from tracker.drivers.motor_emulator import MotorEmulator

from .conftest import free_port, poll

API = "/api/v1"


def _settings(tmp_path: Path, driver: str) -> Any:  # noqa: ANN401
    return load_settings(None, data_dir=str(tmp_path / "data"), viewer_enabled=False,
                         viewer_port=free_port(), audio_enabled=False, driver=driver)


@dataclass(frozen=True)
class Live:
    client: TestClient
    headers: dict[str, str]
    driver: str

    def status(self) -> dict[str, Any]:
        body: dict[str, Any] = self.client.get(f"{API}/status", headers=self.headers).json()
        return body


@pytest.fixture
def live(tmp_path: Path, board: MotorEmulator) -> Iterator[Live]:
    """The service on the emulated serial rig, holding."""
    # A 1 s watchdog: a test machine that stalls the host for 0.1 s must not trip the board.
    driver = f"serial://{board.path}?baud=1000000&rate=250&watchdog_ms=1000"
    with TestClient(create_app(_settings(tmp_path, driver))) as client:
        h = {"X-API-Key": (tmp_path / "data" / "admin.key").read_text().strip()}
        lv = Live(client, h, driver)
        assert poll(lambda: lv.status()["mode"] == "hold", 15.0), lv.status()
        yield lv


@pytest.mark.slow
def test_the_sweep_takes_the_rig_over_measures_its_friction_and_hands_it_back(
        live: Live, board: MotorEmulator) -> None:
    client, h, driver, status = live.client, live.headers, live.driver, live.status
    r = client.post(f"{API}/jobs/friction-id", headers=h,
                    json={"axis": "pan", "source": "live", "voltages": 4})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    assert poll(lambda: status()["driver"]["held_by"] == "the friction-id job", 5.0), status()
    s = status()
    assert s["mode"] == "hold" and s["driver"]["held_axis"] == "pan"
    tilt_before = board.board.twin.load_rad("tilt")
    r = client.post(f"{API}/jobs/friction-id", headers=h, json={"axis": "tilt", "source": "live"})
    assert r.status_code == 409 and "taken over" in r.text
    r = client.put(f"{API}/tracking", headers=h, json={"enabled": True})
    assert r.status_code == 409 and "taken over" in r.text

    def finished() -> dict[str, Any] | None:
        job: dict[str, Any] = client.get(f"{API}/jobs/{job_id}", headers=h).json()
        return job if job["state"] in ("done", "failed", "cancelled") else None

    job = poll(finished, 120.0)
    assert job and job["state"] == "done", job["message"] if job else None
    res = job["result"]
    assert res["driver"] == driver
    # The emulator's twin: the seed's pan axis, Coulomb 0.052 N·m, viscous 8.5e-4 N·m·s/rad.
    for side in ("positive", "negative"):
        assert res[side]["coulomb_nm"] == pytest.approx(0.052, rel=0.05)
        assert res[side]["viscous_nm_s_per_rad"] == pytest.approx(8.5e-4, rel=0.1)
    s = status()
    assert s["driver"]["held_by"] is None and s["mode"] == "hold" and not s["faults"]
    assert board.board.armed
    # The loop kept steering the axis it still had: tilt held where it was all through the sweep.
    assert abs(board.board.twin.load_rad("tilt") - tilt_before) < 0.01


def test_the_live_sweep_needs_a_serial_rig(tmp_path: Path) -> None:
    with TestClient(create_app(_settings(tmp_path, "sim"))) as client:
        h = {"X-API-Key": (tmp_path / "data" / "admin.key").read_text().strip()}
        r = client.post(f"{API}/jobs/friction-id", headers=h, json={"axis": "pan", "source": "live"})
        assert r.status_code == 409 and "serial motor controller" in r.text
        r = client.post(f"{API}/jobs/friction-id", headers=h,
                        json={"axis": "pan", "source": "live", "voltages": 1})
        assert r.status_code == 422 and "voltages" in r.text


def test_a_cancelled_sweep_stops_the_rig_and_hands_it_back(live: Live) -> None:
    client, h, status = live.client, live.headers, live.status
    r = client.post(f"{API}/jobs/friction-id", headers=h, json={"axis": "tilt", "source": "live"})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    assert poll(lambda: status()["driver"]["held_by"] is not None, 10.0), status()
    r = client.post(f"{API}/jobs/{job_id}/cancel", headers=h)
    assert r.status_code in (200, 202), r.text
    job = poll(lambda: (j := client.get(f"{API}/jobs/{job_id}", headers=h).json())["state"]
               in ("cancelled", "failed", "done") and j, 20.0)
    assert job and job["state"] == "cancelled", job
    s = status()
    assert s["driver"]["held_by"] is None and s["mode"] == "hold" and not s["faults"]
