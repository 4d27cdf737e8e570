"""Revocation reaches live sessions and the start banner tells the truth (issue #11 item 4)."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import httpx
import pytest
from starlette.websockets import WebSocketDisconnect

from app.auth import ensure_admin_key
from app.db import Database
from app.main import banner_lines, bind
from app.settings import load_settings

from .conftest import Rig, free_port

API = "/api/v1"
ROOT = Path(__file__).resolve().parents[2]


def new_key(rig: Rig, role: str) -> dict[str, object]:
    r = rig.client.post(f"{API}/keys", headers=rig.h("admin"), json={"name": f"temp {role}", "role": role})
    assert r.status_code == 201
    return r.json()  # type: ignore[no-any-return]


def test_revoking_a_key_closes_its_websockets_at_once(rig: Rig) -> None:
    """Bug: an open WebSocket kept streaming after its key was revoked."""
    doomed, other = new_key(rig, "viewer"), rig.keys["viewer"]
    with (
        rig.client.websocket_connect(f"{API}/telemetry") as ws,
        rig.client.websocket_connect(f"{API}/telemetry") as bystander,
    ):
        ws.send_text(json.dumps({"key": doomed["key"]}))
        bystander.send_text(json.dumps({"key": other}))
        assert ws.receive_json()["type"] == "hello" and bystander.receive_json()["type"] == "hello"
        assert ws.receive_json()["type"] == "frame"
        assert rig.client.delete(f"{API}/keys/{doomed['id']}", headers=rig.h("admin")).status_code == 204
        with pytest.raises(WebSocketDisconnect) as closed:
            for _ in range(1000):  # frames already queued may still arrive; then the close
                ws.receive_json()
        assert bystander.receive_json()["type"] == "frame"
    assert closed.value.code == 4401 and "revoked" in (closed.value.reason or "")


def test_revoking_the_holder_frees_manual_control_at_once(rig: Rig) -> None:
    """Bug: a revoked holder kept the manual-control lock for ~30 s (its idle timeout)."""
    doomed = new_key(rig, "operator")
    holder = {"X-API-Key": str(doomed["key"])}
    assert rig.client.post(f"{API}/control", headers=holder).status_code == 200
    busy = rig.client.put(f"{API}/pointing", headers=rig.h("operator2"), json={"pan_deg": 0, "tilt_deg": 0})
    assert busy.status_code == 409
    assert rig.client.delete(f"{API}/keys/{doomed['id']}", headers=rig.h("admin")).status_code == 204
    status = rig.client.get(f"{API}/status", headers=rig.h("viewer")).json()
    assert status["control_holder"] is None
    r = rig.client.put(f"{API}/pointing", headers=rig.h("operator2"), json={"pan_deg": 0, "tilt_deg": 0})
    assert r.status_code == 200, r.text
    rig.client.delete(f"{API}/pointing", headers=rig.h("operator2"))


def _svc(db: Database, viewer_port: int | None) -> SimpleNamespace:
    viewer = None if viewer_port is None else SimpleNamespace(host="127.0.0.1", port=viewer_port)
    return SimpleNamespace(db=db, viewer=viewer)


def test_banner_mentions_admin_key_only_while_it_is_valid(tmp_path: Path) -> None:
    """Bug: the banner kept saying the first admin key is in data/admin.key after it was revoked."""
    settings = load_settings(None, data_dir=str(tmp_path), viewer_enabled=False)
    db = Database(settings.db_path)
    try:
        ensure_admin_key(db, settings.admin_key_path)
        assert any("admin.key" in line for line in banner_lines(settings, _svc(db, None), 8000))  # type: ignore[arg-type]
        db.revoke_key(db.list_keys()[0].id)
        lines = banner_lines(settings, _svc(db, None), 8000)  # type: ignore[arg-type]
        assert not any("admin.key" in line for line in lines)
    finally:
        db.close()


def test_banner_names_the_ports_actually_bound(tmp_path: Path) -> None:
    """Bug: the banner advertised the 3D view on 8081 when it had bound 8082."""
    settings = load_settings(None, data_dir=str(tmp_path), viewer_port=8081, port=0)
    db = Database(settings.db_path)
    try:
        sock = bind("127.0.0.1", 0)
        port = sock.getsockname()[1]
        sock.close()
        lines = "\n".join(banner_lines(settings, _svc(db, 8082), port))  # type: ignore[arg-type]
    finally:
        db.close()
    assert f"http://127.0.0.1:{port}/" in lines and port != 0
    assert "http://127.0.0.1:8082/" in lines and "8081" not in lines
    # the address browsers use: through the console, on the console's bound port
    assert f"3D view on http://127.0.0.1:{port}/api/v1/view/" in lines


@pytest.mark.slow
def test_tracker_serve_prints_the_ports_it_bound(tmp_path: Path) -> None:
    """Bug: the banner printed the configured ports, not the bound ones (port 0, a taken 3D-view
    port). The real command, on port 0, with the 3D view's port taken by another socket."""
    taken = socket.socket()
    taken.bind(("127.0.0.1", free_port()))
    taken.listen()
    env = dict(
        os.environ,
        PYTHONPATH=str(ROOT),
        TRACKER_DATA_DIR=str(tmp_path),
        TRACKER_AUDIO_ENABLED="false",
        TRACKER_VIEWER_PORT=str(taken.getsockname()[1]),
        TRACKER_LOG_LEVEL="warning",
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", "tracker", "serve", "--host", "127.0.0.1", "--port", "0"],
        env=env,
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        lines: list[str] = []
        deadline = time.monotonic() + 60
        assert proc.stdout is not None
        while time.monotonic() < deadline and not any("viser itself" in line for line in lines):
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
        console = next(line for line in lines if "API docs" in line)
        port = int(console.split("http://127.0.0.1:")[1].split("/")[0])
        assert httpx.get(f"http://127.0.0.1:{port}/api/v1/health", timeout=10).status_code == 200
        view = next(line for line in lines if "3D view on" in line)
        assert f"http://127.0.0.1:{port}/api/v1/view/" in view  # through the console
        viser = next(line for line in lines if "viser itself listens on" in line)
        view_port = int(viser.split("http://127.0.0.1:")[1].split("/")[0])
        assert view_port != taken.getsockname()[1]
        with socket.create_connection(("127.0.0.1", view_port), timeout=5):
            pass
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
        taken.close()
