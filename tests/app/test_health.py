"""Issue #11 item 7: /health answered 200 when the engine was dead. Now 503 with a JSON body
saying why when the control loop is stalled (no tick for longer than health_stall_s) or has
stopped, or the drive is faulted; 200 again once that is over."""

from __future__ import annotations

import math
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
    yield from make_rig(tmp_path, health_stall_s=1.5)  # a busy CI machine gaps ticks ~0.5 s


def svc_of(rig: Rig) -> Any:  # noqa: ANN401 - app.service.Service, reached in-process
    return rig.client.app.state.svc  # type: ignore[attr-defined]


def health(rig: Rig) -> tuple[int, dict[str, Any]]:
    """Both paths' answer (asked until they agree: the state may change between two requests)."""
    for _ in range(20):
        answers = [rig.client.get(p) for p in PATHS]
        if answers[0].status_code == answers[1].status_code:
            break
    assert answers[0].status_code == answers[1].status_code
    return answers[1].status_code, answers[1].json()


def healthy(rig: Rig) -> bool:
    return health(rig)[0] == 200


def test_a_stalled_control_loop_is_503_and_recovers(hrig: Rig) -> None:
    assert poll(lambda: healthy(hrig), 30.0), health(hrig)
    engine = svc_of(hrig).engine
    release = threading.Event()
    original = engine.step_chunk

    def stuck() -> Any:  # noqa: ANN401 - a tick that hangs (a driver call that never returns)
        release.wait(20.0)
        return original()

    engine.step_chunk = stuck
    try:
        assert poll(lambda: health(hrig)[0] == 503, 30.0)
        status, body = health(hrig)
        assert body["ok"] is False and body["error"] == "Unhealthy"
        assert "control loop stalled" in body["detail"] and body["last_tick_age_s"] > 1.5
        assert body["engine_running"] is True  # the task is alive: only the ticks say it is stuck
        loop = hrig.client.get(f"{API}/status", headers=hrig.h("viewer")).json()["loop"]
        assert loop["last_tick_ms_ago"] > 1500.0
    finally:
        engine.step_chunk = original
        release.set()
    assert poll(lambda: (h := health(hrig))[0] == 200 and h[1]["reasons"] == [], 30.0), health(hrig)


def test_a_faulted_drive_is_503_until_cleared(hrig: Rig) -> None:
    assert poll(lambda: healthy(hrig), 30.0)
    svc_of(hrig).engine.driver.latch_fault("pan: over-travel (test)")
    status, body = health(hrig)
    assert status == 503 and body["faults"] == ["pan: over-travel (test)"]
    assert "drive fault latched: pan: over-travel (test)" in body["reasons"]
    assert hrig.client.post(f"{API}/faults/clear", headers=hrig.h("engineer")).status_code == 200
    assert poll(lambda: healthy(hrig), 30.0)


def test_a_stopped_engine_is_503(hrig: Rig) -> None:
    assert poll(lambda: healthy(hrig), 30.0)
    svc_of(hrig).engine.stop()
    assert poll(lambda: health(hrig)[0] == 503, 30.0)
    assert health(hrig)[1]["reasons"] == ["the engine loop is not running"]


def test_the_status_keeps_the_loops_warm_up_apart(hrig: Rig) -> None:
    loop = hrig.client.get(f"{API}/status", headers=hrig.h("viewer")).json()["loop"]
    period_s = loop["period_ms"] / 1e3
    assert loop["warm_up_ticks"] == math.ceil(1.0 / period_s)  # tracker.engine.WARM_UP_S
    assert loop["warm_up_max_lateness_ms"] >= 0.0 and loop["max_lateness_ms"] >= 0.0
