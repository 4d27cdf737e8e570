"""Found by running the console as a user would, with ``loop_process = true`` (and checked
against the loop in a thread): each test here failed before its fix."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.app.conftest import make_rig
from tests.processes import process_gone
from tests.tracker.audio.conftest import FS_HZ, example_array, free_field
from tracker.audio.sources import write_wav

API = "/api/v1"


def one_talker_wav(path: Path) -> Path:
    """A talker at 20° for 2 s on the 4-mic square (16 kHz)."""
    array = example_array("square4_65mm")
    quiet = 0.001 * np.random.default_rng(0).standard_normal((4, FS_HZ // 2))
    audio = np.concatenate([quiet, free_field(array, math.radians(20.0), duration_s=2.0, seed=1)], axis=1)
    write_wav(path, FS_HZ, audio)
    return path


def status(rig: Any) -> dict[str, Any]:  # noqa: ANN401 - the conftest's Rig
    r = rig.client.get(f"{API}/status", headers=rig.h("viewer"))
    assert r.status_code == 200, r.text
    out: dict[str, Any] = r.json()
    return out


@pytest.mark.parametrize("loop_process", [True, False], ids=["process", "thread"])
def test_tracking_turned_off_stays_off_after_a_restart_with_audio(tmp_path: Path, loop_process: bool) -> None:
    """Bug: with the room's audio on (the default) ``track_on_start`` turned tracking on at every
    start, after the stored "tracking off" had been restored (docs/operations.md: tracking on/off
    survives a restart). ``track_on_start`` is for a fresh start, with nothing stored."""
    wav = one_talker_wav(tmp_path / "talker.wav")
    data = tmp_path / "data"
    data.mkdir()
    settings = {"audio_enabled": True, "audio_input": f"wav:{wav}", "loop_process": loop_process}
    for rig in make_rig(data, **settings):
        assert status(rig)["tracking"] is True  # a fresh start follows the talker
        r = rig.client.put(f"{API}/tracking", headers=rig.h("operator"), json={"enabled": False})
        assert r.status_code == 200 and r.json()["tracking"] is False, r.text
    for rig in make_rig(data, **settings):
        st = status(rig)
        assert st["tracking"] is False and st["settings_warnings"] == [], st


SERVICE = """
import asyncio, os, sys
sys.path.insert(0, {root!r})
from app.work import WorkPool
from app.workers import WorkerPool
from tests.tracker.test_loop_process import build_twin
from tracker.loop_process.proxy import LoopProcess

async def main():
    heavy = WorkPool(workers=1)
    jobs = WorkerPool(1)
    proc = LoopProcess(build_twin, 0.01)
    task = asyncio.create_task(proc.run())
    heavy_pid = heavy._pool().submit(os.getpid).result(60)
    job_pid = jobs._executor.submit(os.getpid).result(60)
    print(proc.pid, heavy_pid, job_pid, proc._shared.name, flush=True)
    await task

if __name__ == "__main__":
    asyncio.run(main())
"""


def test_a_killed_service_leaves_no_worker_and_no_shared_memory(tmp_path: Path) -> None:
    """Bug: after a ``kill -9`` of the service the loop's process stopped, but the heavy and job
    workers (spawned pools) lived on as orphans, and with them the resource tracker, which then
    never unlinked the loop's shared memory: one /dev/shm segment and two processes per crash."""
    root = Path(__file__).resolve().parents[2]
    script = tmp_path / "service.py"
    script.write_text(SERVICE.format(root=str(root)))
    service = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        assert service.stdout is not None
        loop_pid, heavy_pid, job_pid, shm = service.stdout.readline().split()
        pids = [int(loop_pid), int(heavy_pid), int(job_pid)]
        segment = Path("/dev/shm") / shm
        assert segment.exists() and not any(process_gone(p) for p in pids)
        os.kill(service.pid, signal.SIGKILL)
        service.wait(10)
        end = time.monotonic() + 10.0
        while (segment.exists() or not all(process_gone(p) for p in pids)) and time.monotonic() < end:
            time.sleep(0.1)
        assert [p for p in pids if not process_gone(p)] == [], "a process outlived the service"
        assert not segment.exists(), f"{segment} outlived the service"
    finally:
        if service.poll() is None:
            service.kill()
        for p in pids if "pids" in locals() else []:
            if not process_gone(p):
                os.kill(p, signal.SIGKILL)


def test_the_last_telemetry_frame_says_fault_when_the_loops_process_dies(tmp_path: Path) -> None:
    """Bug: when the loop's process died, telemetry stopped on the last frame it had sent —
    mode "manual" or "tracking", the axes' command still on — while status said "fault": a
    WebSocket client (a room-control system, the console's plot) saw a healthy rig frozen. With
    the loop in a thread a fault reaches the frames too."""
    for rig in make_rig(tmp_path, loop_process=True):
        _kill_the_loop_and_read_the_last_frame(rig)


def _kill_the_loop_and_read_the_last_frame(rig: Any) -> None:  # noqa: ANN401 - the conftest's Rig
    from tests.app.conftest import poll

    hub = rig.client.app.state.svc.hub
    r = rig.client.put(f"{API}/pointing", headers=rig.h("operator"), json={"pan_deg": 10.0, "tilt_deg": 0.0})
    assert r.status_code == 200, r.text
    assert poll(lambda: hub.latest_frame is not None and hub.latest_frame["mode"] == "manual", 5.0)
    os.kill(status(rig)["driver"]["loop_process"]["pid"], signal.SIGKILL)
    assert poll(lambda: status(rig)["mode"] == "fault", 5.0)
    frame = poll(lambda: hub.latest_frame if hub.latest_frame["mode"] == "fault" else None, 2.0)
    assert frame is not None, f"the last frame still says {hub.latest_frame['mode']}"
    assert frame["pan_u_v"] == 0.0 and frame["tilt_u_v"] == 0.0  # the axes are stopped
    assert frame["pan_deg"] == pytest.approx(status(rig)["pan_deg"], abs=0.01)
