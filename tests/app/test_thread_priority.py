"""Issue 10 item 6: service_threads_priority puts the service's threads in SCHED_FIFO below the
control loop's (a thread holding the interpreter lock is then not preempted by other processes
while the loop waits for it); the worker processes stay in the normal class; status says what
the threads got; a priority not below the loop's is refused at start-up."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.settings import load_settings
from tracker.errors import ConfigError

from .conftest import Rig, make_rig, poll

API = "/api/v1"
pytestmark = pytest.mark.skipif(not hasattr(os, "SCHED_RESET_ON_FORK"), reason="Linux scheduling classes")


def _normal_again() -> None:
    for name in os.listdir(f"/proc/{os.getpid()}/task"):
        with contextlib.suppress(OSError):
            os.sched_setscheduler(int(name), os.SCHED_OTHER, os.sched_param(0))


@pytest.fixture
def prig(tmp_path: Path) -> Iterator[Rig]:
    try:
        yield from make_rig(tmp_path, control_loop_priority=20, service_threads_priority=4)
    finally:
        _normal_again()  # the service ran in this process: so did the test's threads


def test_the_service_threads_run_below_the_loop_and_the_workers_in_the_normal_class(prig: Rig) -> None:
    def loop() -> dict:  # type: ignore[type-arg]
        return prig.client.get(f"{API}/status", headers=prig.h("viewer")).json()["loop"]

    first = poll(lambda: loop()["ticks"] > 0 and loop())
    if first["priority"] != 20:
        pytest.skip("real-time priorities refused here")
    status = poll(lambda: (s := loop())["service_threads_priority"] == 4 and s)
    assert status and status["priority"] == 20
    policies = {}
    for name in os.listdir(f"/proc/{os.getpid()}/task"):
        with contextlib.suppress(OSError):
            policies[int(name)] = (os.sched_getscheduler(int(name)) & ~os.SCHED_RESET_ON_FORK,
                                   os.sched_getparam(int(name)).sched_priority)
    assert (os.SCHED_FIFO, 20) in policies.values()  # the loop
    assert sum(p == (os.SCHED_FIFO, 4) for p in policies.values()) >= 2  # the web side's threads
    svc = prig.client.app.state.svc  # type: ignore[attr-defined]
    pids = [p.pid for p in (svc.work._executor._processes.values() if svc.work._executor else [])]
    assert pids
    for pid in pids:  # in the normal class (one started later by a real-time thread too: test_realtime)
        assert os.sched_getscheduler(pid) == os.SCHED_OTHER


def test_a_service_priority_not_below_the_loop_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="service_threads_priority.*below control_loop_priority"):
        load_settings(None, data_dir=str(tmp_path), control_loop_priority=10, service_threads_priority=10)
    with pytest.raises(ConfigError, match="service_threads_priority"):
        load_settings(None, data_dir=str(tmp_path), service_threads_priority=3)  # loop at 0


def test_a_refused_priority_leaves_the_threads_as_they_were(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Without CAP_SYS_NICE or RLIMIT_RTPRIO (a unit without LimitRTPRIO) the service keeps
    serving in the normal class, says so in the log, and the status says 0."""
    import tracker.realtime

    calls: list[int] = []

    def refuse(priority: int) -> tuple[int, str | None]:
        calls.append(priority)
        return 0, "[Errno 1] Operation not permitted"

    monkeypatch.setattr(tracker.realtime, "raise_process_threads", refuse)
    rigs = make_rig(tmp_path, control_loop_priority=20, service_threads_priority=4)
    rig = next(rigs)
    try:
        status = poll(lambda: calls and rig.client.get(f"{API}/status", headers=rig.h("viewer")).json())
        assert calls == [4] and status["loop"]["service_threads_priority"] == 0
        assert rig.client.get(f"{API}/health").status_code == 200
    finally:
        rigs.close()  # the service stops
    assert any("service_threads_priority 4 refused" in r.message for r in caplog.records)
