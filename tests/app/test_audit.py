"""Issue #11 item 7: "logs do not say which key did what". Each change through the API writes an
audit entry with the key's id, name and role; admins read it (paged, newest first), nobody
else; no entry holds a secret; a held jog button is one entry, not one per renewal."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.modelio import model_to_json
from tracker.plant.model import AxisModel

from .conftest import Rig, make_rig

API = "/api/v1"


@pytest.fixture(scope="module")
def arig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    yield from make_rig(tmp_path_factory.mktemp("audit"))


def svc_of(rig: Rig) -> Any:  # noqa: ANN401 - app.service.Service, reached in-process
    return rig.client.app.state.svc  # type: ignore[attr-defined]


def key_ids(rig: Rig) -> dict[str, int]:
    out = {}
    for role in ("viewer", "operator", "engineer", "admin"):
        out[role] = rig.client.get(f"{API}/whoami", headers=rig.h(role)).json()["key_id"]
    return out


def entries(rig: Rig, **params: Any) -> dict[str, Any]:  # noqa: ANN401
    r = rig.client.get(f"{API}/audit", headers=rig.h("admin"), params=params)
    assert r.status_code == 200, r.text
    body: dict[str, Any] = r.json()
    return body


def ok(r: Any, status: int = 200) -> None:  # noqa: ANN401 - a response
    assert r.status_code == status, r.text


def test_each_change_is_logged_with_the_key_and_role(arig: Rig) -> None:
    c, h = arig.client, arig.h
    ids = key_ids(arig)
    start = entries(arig, limit=1)["entries"]
    first_id = start[0]["id"] if start else 0
    ok(c.put(f"{API}/pointing", headers=h("operator"), json={"pan_deg": 10.0, "tilt_deg": 2.0}))
    for _ in range(4):  # a held jog button re-sends its press
        ok(c.put(f"{API}/jog/pan", headers=h("operator"), json={"rate_deg_s": 5.0}))
    ok(c.delete(f"{API}/jog/pan", headers=h("operator")))
    ok(c.delete(f"{API}/pointing", headers=h("operator")))
    ok(c.put(f"{API}/tracking", headers=h("operator"), json={"enabled": False}))
    ok(c.put(f"{API}/presets/stage", headers=h("operator"), json={"pan_deg": 5.0, "tilt_deg": 1.0}))
    ok(c.post(f"{API}/presets/stage/recall", headers=h("operator")))
    ok(c.delete(f"{API}/presets/stage", headers=h("operator")), 204)
    ok(c.delete(f"{API}/pointing", headers=h("operator")))
    kp = svc_of(arig).engine.gains("tilt").kp_v_per_rad
    ok(c.put(f"{API}/axes/tilt/gains", headers=h("engineer"), json={"gains": {"kp_v_per_rad": 0.95 * kp}}))
    svc = svc_of(arig)
    mid = svc.db.add_measurement("fit.csv", "pan", "t,u,theta\n", 0, 1e-3)
    vid = svc.db.add_version(mid, None, "base", model_to_json(AxisModel.for_axis("pan"), "pan"), {})
    ok(c.put(f"{API}/axes/pan/model", headers=h("engineer"), json={"version_id": vid}))
    created = c.post(f"{API}/keys", headers=h("admin"), json={"name": "night shift", "role": "operator"})
    ok(created, 201)
    new_key, new_id = created.json()["key"], created.json()["id"]
    ok(c.delete(f"{API}/keys/{new_id}", headers=h("admin")), 204)
    ok(c.put(f"{API}/axes/pan/gains", headers=h("engineer"), json={"gains": {"kp_v_per_rad": 1e9}}), 422)

    got = [e for e in entries(arig, limit=100)["entries"] if e["id"] > first_id]
    got.reverse()  # oldest first, to compare with what was done
    summary = [(e["action"], e["target"], e["role"], e["key_id"]) for e in got]
    op, eng, adm = ids["operator"], ids["engineer"], ids["admin"]
    assert summary == [
        ("pointing.set", "", "operator", op),
        ("jog.start", "pan", "operator", op),  # four presses, one entry
        ("jog.stop", "pan", "operator", op),
        ("pointing.release", "", "operator", op),
        ("tracking.set", "", "operator", op),
        ("preset.store", "stage", "operator", op),
        ("preset.recall", "stage", "operator", op),
        ("preset.delete", "stage", "operator", op),
        ("pointing.release", "", "operator", op),
        ("gains.set", "tilt", "engineer", eng),
        ("model.set", "pan", "engineer", eng),
        ("key.create", str(new_id), "admin", adm),
        ("key.revoke", str(new_id), "admin", adm),
    ]  # the refused gains (422) changed nothing and are not logged
    assert got[0]["detail"] == {"pan_deg": 10.0, "tilt_deg": 2.0}
    assert got[0]["key_name"] == "test operator"
    assert got[9]["detail"] == {"changes": {"kp_v_per_rad": pytest.approx(0.95 * kp)}}
    assert got[11]["detail"] == {"name": "night shift", "role": "operator"}
    assert all(e["t_s"] > 1.7e9 for e in got)
    text = json.dumps(entries(arig, limit=500))
    assert new_key not in text and all(k not in text for k in arig.keys.values())  # no secrets


def test_only_admins_read_the_audit_log(arig: Rig) -> None:
    for role in ("viewer", "operator", "engineer"):
        assert arig.client.get(f"{API}/audit", headers=arig.h(role)).status_code == 403
    assert arig.client.get(f"{API}/audit").status_code == 401


def test_the_log_pages_newest_first(arig: Rig) -> None:
    for pan in (1.0, 2.0, 3.0):
        body = {"pan_deg": pan, "tilt_deg": 0}
        ok(arig.client.put(f"{API}/pointing", headers=arig.h("operator"), json=body))
    page1 = entries(arig, limit=2)
    page2 = entries(arig, limit=2, before_id=page1["next_before_id"])
    pans = [e["detail"]["pan_deg"] for e in page1["entries"] + page2["entries"][:1]]
    assert pans == [3.0, 2.0, 1.0]
    ids = [e["id"] for e in page1["entries"] + page2["entries"]]
    assert ids == sorted(ids, reverse=True) and len(set(ids)) == 4
    assert arig.client.get(f"{API}/audit", headers=arig.h("admin"), params={"limit": 0}).status_code == 422


def test_a_secret_in_a_detail_is_redacted(tmp_path: Path) -> None:
    from app.audit import REDACTED, AuditLog
    from app.auth import Principal, Role
    from app.db import Database

    log = AuditLog(Database(tmp_path / "a.sqlite3"), coalesce_s=0.0)
    who = Principal(7, "ops", Role.admin)
    detail = {"key": "abc", "note": "3dat_abcdef", "n": [1, {"token": 2}]}
    assert asyncio.run(log.record(who, "settings.set", "x", detail))
    (entry,) = log.page()
    assert entry.detail == {"key": REDACTED, "note": REDACTED, "n": [1, {"token": REDACTED}]}
    assert (entry.key_id, entry.key_name, entry.role) == (7, "ops", "admin")
