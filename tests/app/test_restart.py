"""Issue #11 item 5: settings survive a restart. Gains, the controller's model and tracking are
changed through the API, the service stops, a new one starts on the same data folder and has
them back before its control loop's first tick; stored values the checks now refuse fall back
to the defaults with a warning in status instead of stopping the start; the settings store
writes atomically, even when the process is killed mid-write."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from app import console_state
from app.db import Database
from app.modelio import model_to_json
from app.persist import SettingsStore
from tracker.errors import DataError
from tracker.plant.model import AxisModel

from .conftest import Rig, make_rig

API = "/api/v1"


def svc_of(rig: Rig) -> Any:  # noqa: ANN401 - app.service.Service, reached in-process
    return rig.client.app.state.svc  # type: ignore[attr-defined]


def offset_pan() -> AxisModel:
    return AxisModel.for_axis("pan", ["offset"], {"offset.torque": 0.004})


def change_everything(rig: Rig) -> dict[str, Any]:
    """PUT a pan model, tilt gains and tracking on; returns what the engine then holds."""
    svc = svc_of(rig)
    mid = svc.db.add_measurement("fit.csv", "pan", "t,u,theta\n", 0, 1e-3)
    vid = svc.db.add_version(mid, None, "+offset", model_to_json(offset_pan(), "pan"), {})
    r = rig.client.put(f"{API}/axes/pan/model", headers=rig.h("engineer"), json={"version_id": vid})
    assert r.status_code == 200, r.text
    kp = svc.engine.gains("tilt").kp_v_per_rad
    r = rig.client.put(f"{API}/axes/tilt/gains", headers=rig.h("engineer"),
                       json={"gains": {"kp_v_per_rad": 0.9 * kp}})
    assert r.status_code == 200, r.text
    r = rig.client.put(f"{API}/tracking", headers=rig.h("operator"), json={"enabled": True})
    assert r.status_code == 200 and r.json()["tracking"] is True, r.text
    e = svc.engine
    return {"pan_model": e.model("pan"), "pan_gains": e.gains("pan"), "tilt_gains": e.gains("tilt")}


def test_gains_model_and_tracking_are_restored_before_the_first_tick(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Bug: applied gains, the controller's model and tracking vanished on restart (tracking
    started off: a room that reboots at night stopped following talkers)."""
    for rig in make_rig(tmp_path):
        before = change_everything(rig)
        assert before["pan_model"].effects == ("offset",)
    seen: list[tuple[int, bool]] = []
    original = console_state.ConsoleState.restore

    def spy(self: console_state.ConsoleState, engine: Any) -> list[str]:  # noqa: ANN401
        seen.append((engine.timing().ticks, engine._running))
        return original(self, engine)

    monkeypatch.setattr(console_state.ConsoleState, "restore", spy)
    for rig in make_rig(tmp_path):
        e = svc_of(rig).engine
        assert seen == [(0, False)]  # restored before the loop ran
        assert e.model("pan").effects == ("offset",)
        assert e.model("pan").params == pytest.approx(before["pan_model"].params)
        assert e.gains("pan") == before["pan_gains"]  # the design on the restored model
        assert e.gains("tilt") == before["tilt_gains"]
        st = rig.client.get(f"{API}/status", headers=rig.h("viewer")).json()
        assert st["tracking"] is True and st["settings_warnings"] == []


def test_a_new_model_replaces_stored_gains_and_tracking_off_is_kept(tmp_path: Path) -> None:
    for rig in make_rig(tmp_path):
        change_everything(rig)
        assert rig.client.put(f"{API}/tracking", headers=rig.h("operator"),
                              json={"enabled": False}).status_code == 200
        svc = svc_of(rig)
        mid = svc.db.add_measurement("tilt.csv", "tilt", "t,u,theta\n", 0, 1e-3)
        vid = svc.db.add_version(mid, None, "tilt", model_to_json(AxisModel.for_axis("tilt"), "tilt"), {})
        r = rig.client.put(f"{API}/axes/tilt/model", headers=rig.h("engineer"), json={"version_id": vid})
        assert r.status_code == 200, r.text
        designed = svc.engine.gains("tilt")
        assert svc.store.get("console.gains.tilt") is None  # the redesign replaced them
    for rig in make_rig(tmp_path):
        st = rig.client.get(f"{API}/status", headers=rig.h("viewer")).json()
        assert st["tracking"] is False and st["settings_warnings"] == []
        assert svc_of(rig).engine.gains("tilt") == designed


def test_stored_values_the_checks_now_refuse_fall_back_to_defaults_with_a_warning(tmp_path: Path) -> None:
    """A stored value that no longer validates must not stop the service from starting."""
    for rig in make_rig(tmp_path):
        change_everything(rig)
    store = SettingsStore(Database(tmp_path / "console.sqlite3"))
    store.put("console.tracking", {"enabled": "yes"})  # not a boolean
    store.put("console.model.tilt", {"model": {"axis": "tilt"}, "version_id": 1})  # half a model
    for rig in make_rig(tmp_path, min_phase_margin_deg=89.0):  # a floor no gain set meets
        svc = svc_of(rig)
        st = rig.client.get(f"{API}/status", headers=rig.h("viewer")).json()
        warned = {w.split(":")[0] for w in st["settings_warnings"]}
        assert warned == {"console.model.pan", "console.model.tilt", "console.gains.tilt",
                          "console.tracking"}, st["settings_warnings"]
        assert any("phase margin" in w or "redesign refused" in w for w in st["settings_warnings"])
        assert st["tracking"] is False
        assert svc.engine.model("pan").effects == ()  # the default model
        assert rig.client.get(f"{API}/health").status_code == 200  # it started and runs
        metrics = rig.client.get("/metrics", headers=rig.h("viewer")).text
        assert "tracker_settings_not_restored 4.0" in metrics


def test_the_store_refuses_non_finite_values_whole(tmp_path: Path) -> None:
    store = SettingsStore(Database(tmp_path / "s.sqlite3"))
    store.write({"a": 1, "b": [1, 2]}, version=3)
    with pytest.raises(DataError, match="'c'"):
        store.write({"a": 2, "c": math.nan})
    got = store.get("a")
    assert got is not None and got.value == 1 and got.version == 3 and store.get("c") is None
    assert set(store.get_prefix("")) == {"a", "b"}
    store.delete("a")
    assert store.get("a") is None and store.get_prefix("b")["b"].value == [1, 2]
    store.put("x_y", 1)
    store.put("xzy", 2)
    assert set(store.get_prefix("x_")) == {"x_y"}  # "_" is not a wildcard


WRITER = """
import sys
from app.db import Database
from app.persist import SettingsStore
store = SettingsStore(Database(sys.argv[1]))
print("ready", flush=True)
gen = 0
while True:
    gen += 1
    store.write({f"k{i:03d}": {"gen": gen, "pad": "x" * 200} for i in range(300)}, version=1)
"""


@pytest.mark.parametrize("kill_after_s", [0.2, 0.45, 0.7], ids=["early", "middle", "late"])
def test_kill_9_mid_write_leaves_one_whole_generation(tmp_path: Path, kill_after_s: float) -> None:
    """A process writing 300 keys per transaction, killed with SIGKILL at some moment: every
    key read afterwards comes from the same write."""
    path = tmp_path / "s.sqlite3"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(path)], stdout=subprocess.PIPE, env=env)
    assert proc.stdout is not None and proc.stdout.readline().strip() == b"ready"
    time.sleep(kill_after_s)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(10)
    rows = SettingsStore(Database(path)).get_prefix("k")
    gens = {json.dumps(s.value["gen"]) for s in rows.values()}
    assert len(rows) in {0, 300} and len(gens) <= 1, gens


def test_restore_setting_is_how_any_part_restores_its_own(tmp_path: Path) -> None:
    """The generic path other parts use (e.g. the audio policy): applied when the check passes;
    logged, listed and skipped when it refuses or the stored shape has another version."""
    state = console_state.ConsoleState(SettingsStore(Database(tmp_path / "s.sqlite3")))
    state.store.write({"audio.policy": {"hold_s": 2.0}}, version=2)
    applied: list[float] = []

    def apply(value: dict[str, float]) -> str:
        if not 0.0 < value["hold_s"] <= 10.0:
            raise ValueError(f"hold_s {value['hold_s']} outside (0, 10]")
        applied.append(value["hold_s"])
        return "ok"

    assert state.restore_setting("audio.policy", apply, version=2) is True and applied == [2.0]
    assert state.restore_setting("audio.nothing", apply) is False and state.warnings == []
    assert state.restore_setting("audio.policy", apply, version=3) is False
    state.store.write({"audio.policy": {"hold_s": 99.0}}, version=2)
    assert state.restore_setting("audio.policy", apply, version=2) is False and applied == [2.0]
    assert len(state.warnings) == 2 and "hold_s 99.0 outside" in state.warnings[1]
    state.clear_warnings("audio.policy")
    assert state.warnings == []
