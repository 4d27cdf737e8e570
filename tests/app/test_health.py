"""Issue #11 item 7: /health answered 200 when the engine was dead. Now 503 with a JSON body
saying why when the control loop is stalled (no tick for longer than health_stall_s) or has
stopped, or the drive is faulted; 200 again once that is over."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .conftest import Rig, make_rig, poll

API = "/api/v1"
PATHS = ("/health", f"{API}/health")


@pytest.fixture
def hrig(tmp_path: Path) -> Iterator[Rig]:
    yield from make_rig(tmp_path, health_stall_s=0.3)


def svc_of(rig: Rig) -> Any:  # noqa: ANN401 - app.service.Service, reached in-process
    return rig.client.app.state.svc  # type: ignore[attr-defined]


def health(rig: Rig) -> tuple[int, dict[str, Any]]:
    answers = [rig.client.get(p) for p in PATHS]
    assert answers[0].status_code == answers[1].status_code
    return answers[1].status_code, answers[1].json()


def healthy(rig: Rig) -> bool:
    return health(rig)[0] == 200


def test_a_stalled_control_loop_is_503_and_recovers(hrig: Rig) -> None:
    assert poll(lambda: healthy(hrig), 10.0), health(hrig)
    engine = svc_of(hrig).engine
    release = threading.Event()
    original = engine.step_chunk

    def stuck() -> Any:  # noqa: ANN401 - a tick that hangs (a driver call that never returns)
        release.wait(20.0)
        return original()

    engine.step_chunk = stuck
    try:
        assert poll(lambda: health(hrig)[0] == 503, 5.0)
        status, body = health(hrig)
        assert body["ok"] is False and body["error"] == "Unhealthy"
        assert "control loop stalled" in body["detail"] and body["last_tick_age_s"] > 0.3
        assert body["engine_running"] is True  # the task is alive: only the ticks say it is stuck
        loop = hrig.client.get(f"{API}/status", headers=hrig.h("viewer")).json()["loop"]
        assert loop["last_tick_ms_ago"] > 300.0
    finally:
        engine.step_chunk = original
        release.set()
    assert poll(lambda: healthy(hrig), 5.0), health(hrig)
    assert health(hrig)[1]["reasons"] == []


def test_a_faulted_drive_is_503_until_cleared(hrig: Rig) -> None:
    assert poll(lambda: healthy(hrig), 10.0)
    svc_of(hrig).engine.driver.latch_fault("pan: over-travel (test)")
    status, body = health(hrig)
    assert status == 503 and body["faults"] == ["pan: over-travel (test)"]
    assert "drive fault latched: pan: over-travel (test)" in body["reasons"]
    assert hrig.client.post(f"{API}/faults/clear", headers=hrig.h("engineer")).status_code == 200
    assert healthy(hrig)


def test_a_stopped_engine_is_503(hrig: Rig) -> None:
    assert poll(lambda: healthy(hrig), 10.0)
    svc_of(hrig).engine.stop()
    assert poll(lambda: health(hrig)[0] == 503, 5.0)
    assert health(hrig)[1]["reasons"] == ["the engine loop is not running"]
