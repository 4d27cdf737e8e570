"""tracker.loop_process: the engine in its own process — errors carried back as their types, the
telemetry ring, a pushed target followed, and the process stopping when the service dies."""

from __future__ import annotations

import asyncio
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.processes import process_gone
from tracker.engine import Engine, EngineConfig
from tracker.errors import ConfigError, ModelRefused
from tracker.loop_process.shared import RING_SLOTS, SharedLoop
from tracker.loop_process.wire import CarriedError
from tracker.realtime import LoopTiming
from tracker.targets import ManualTarget
from tracker.telemetry import EngineStatus, TelemetrySnapshot

ROOT = Path(__file__).resolve().parents[2]


def build_twin(chunk_s: float) -> Engine:
    """The loop's process builds this (spawned: imported by name)."""
    from tracker.drivers.sim import SimDriver

    return Engine(SimDriver(), EngineConfig(chunk_s=chunk_s))


def build_refused(rig_file: str) -> Engine:
    """A build that fails in the loop's process, as a bad rig file does."""
    raise ConfigError(f"rig file {rig_file}: line 3: 'inertia.J' is -1 (must be > 0)")


def test_a_build_refused_in_the_loops_process_is_raised_in_the_service_as_is() -> None:
    from tracker.loop_process.proxy import LoopProcess

    with pytest.raises(ConfigError, match=r"rig file bad.json: line 3: 'inertia.J' is -1"):
        LoopProcess(build_refused, "bad.json")


def test_a_carried_error_keeps_its_type_message_and_figures() -> None:
    exc = CarriedError.of(ModelRefused("pan model refused: k-step error 3x", {"ratio": 3.0})).rebuild()
    assert type(exc) is ModelRefused and isinstance(exc, ConfigError)
    assert str(exc) == "pan model refused: k-step error 3x" and exc.figures == {"ratio": 3.0}


def _snap(k: int) -> TelemetrySnapshot:
    return TelemetrySnapshot(k * 1e-3, 0.1, -0.1, 0.0, 0.0, 1.0, -1.0, "manual", False, "manual")


def test_the_ring_gives_snapshots_in_order_and_skips_what_it_no_longer_holds() -> None:
    shared = SharedLoop.create()
    try:
        status = EngineStatus(0.0, 0.1, -0.1, 0.0, 0.0, "manual", False, ("pan: over-travel",), None)
        timing = LoopTiming(1e-3, 0, 0.0, 0.0, 0.0, 0, 0, True, True)
        for k in range(10):
            shared.write_chunk(_snap(k), status, True, timing, math.nan)
        got, cursor = shared.read_snapshots(0)
        assert [s.t_s for s in got] == pytest.approx([k * 1e-3 for k in range(10)]) and cursor == 10
        assert got[0] == _snap(0)
        for k in range(10, 10 + RING_SLOTS + 5):  # the reader fell a whole ring behind
            shared.write_chunk(_snap(k), status, True, timing, math.nan)
        got, cursor = shared.read_snapshots(cursor)
        assert cursor == 15 + RING_SLOTS and len(got) == RING_SLOTS - 1
        assert got[-1].t_s == pytest.approx((14 + RING_SLOTS) * 1e-3)
        assert all(b.t_s > a.t_s for a, b in zip(got, got[1:], strict=False))
        read = shared.read_status()
        assert read is not None and read[0].faults == ("pan: over-travel",) and read[1] is True
    finally:
        shared.close()
        shared.unlink()


def test_the_loops_process_follows_a_target_pushed_by_the_service() -> None:
    from tracker.loop_process.proxy import LoopProcess

    async def scenario() -> tuple[float, float, str]:
        proc = LoopProcess(build_twin, 0.01)
        task = asyncio.create_task(proc.run())
        try:
            proc.set_target_source(ManualTarget(0.3, -0.1, name="talker test"))
            proc.set_tracking(True)
            end = time.monotonic() + 10.0
            while time.monotonic() < end:
                st = proc.status()
                if abs(st.pan_rad - 0.3) < 0.005 and abs(st.tilt_rad + 0.1) < 0.005:
                    break
                await asyncio.sleep(0.05)
            return st.pan_rad, st.tilt_rad, st.mode
        finally:
            proc.stop()
            await task
            await proc.close()

    pan, tilt, mode = asyncio.run(scenario())
    assert pan == pytest.approx(0.3, abs=0.005) and tilt == pytest.approx(-0.1, abs=0.005)
    assert mode == "tracking"


class CountingTarget:
    """A talker tracker that counts how often it is asked."""

    name = "counting"

    def __init__(self, pan_rad: float, tilt_rad: float) -> None:
        self.asked = 0
        self.where = (pan_rad, tilt_rad)

    def target_at(self, t_s: float) -> tuple[float, float]:
        self.asked += 1
        return self.where


def test_the_talker_tracker_is_not_asked_while_tracking_is_off_and_no_old_target_is_kept() -> None:
    from tracker.loop_process.proxy import LoopProcess

    async def scenario() -> tuple[int, int, float]:
        proc = LoopProcess(build_twin, 0.01)
        task = asyncio.create_task(proc.run())
        source = CountingTarget(0.3, 0.0)
        try:
            proc.set_target_source(source)
            proc.set_tracking(True)
            while source.asked == 0:
                await asyncio.sleep(0.01)
            proc.set_tracking(False)
            await asyncio.sleep(0.1)  # a chunk for the status to say tracking is off
            asked_before = source.asked
            await asyncio.sleep(0.5)
            asked_off = source.asked - asked_before
            pushed_off = proc._shared.read_target()
            source.where = (-0.2, 0.0)
            proc.set_tracking(True)
            end = time.monotonic() + 10.0
            while time.monotonic() < end and abs(proc.status().pan_rad + 0.2) > 0.005:
                await asyncio.sleep(0.05)
            return asked_off, source.asked, proc.status().pan_rad if pushed_off is None else math.nan
        finally:
            proc.stop()
            await task
            await proc.close()

    asked_off, asked, pan = asyncio.run(scenario())
    assert asked_off == 0, f"asked {asked_off} times in 0.5 s with tracking off"
    assert asked > 1
    assert pan == pytest.approx(-0.2, abs=0.005)  # the target withdrawn, then the new one followed


SERVICE = """
import asyncio, sys
sys.path.insert(0, {root!r})
from tests.tracker.test_loop_process import build_twin
from tracker.loop_process.proxy import LoopProcess

async def main():
    proc = LoopProcess(build_twin, 0.01)
    task = asyncio.create_task(proc.run())
    print(proc.pid, flush=True)
    await task

if __name__ == "__main__":
    asyncio.run(main())
"""


def test_the_loops_process_stops_when_the_service_dies(tmp_path: Path) -> None:
    script = tmp_path / "service.py"
    script.write_text(SERVICE.format(root=str(ROOT)))
    service = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        assert service.stdout is not None
        child = int(service.stdout.readline())
        time.sleep(0.3)
        assert not process_gone(child)
        os.kill(service.pid, signal.SIGKILL)
        service.wait(10)
        end = time.monotonic() + 10.0
        while not process_gone(child) and time.monotonic() < end:
            time.sleep(0.05)
        assert process_gone(child), "the loop's process outlived the service"
    finally:
        if service.poll() is None:
            service.kill()
