"""One version store for the console and the command line: `tracker model fit|history --db` reads
and writes the versions the console shows (the database the running app created), each with its
error budget; bad files are refused and a failed write leaves the database as it was."""

from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path

import pytest

from tracker.cli import main
from tracker.workbench.experiments.experiments import generate_measurement, random_hidden_model
from tracker.workbench.measurements.data import Measurement, format_log, parse_log
from tracker.workbench.version_db import ConsoleDatabase

from .conftest import Rig

API = "/api/v1/workbench"


@pytest.fixture(scope="module")
def offset_csv() -> str:
    truth = random_hidden_model("pan", ["offset"], seed=11)
    return format_log(generate_measurement(truth, duration_s=10.0, seed=6))


def _versions(rig: Rig, mid: int) -> list[dict]:  # type: ignore[type-arg]
    return rig.client.get(f"{API}/measurements/{mid}/versions", headers=rig.h("viewer")).json()


def test_console_and_cli_share_one_history(
    rig: Rig, offset_csv: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = rig.data_dir / "console.sqlite3"
    r = rig.client.post(
        f"{API}/measurements",
        headers=rig.h("engineer"),
        files={"file": ("shared.csv", offset_csv.encode(), "text/csv")},
        data={"axis": "pan"},
    )
    assert r.status_code == 201, r.text
    mid = r.json()["id"]
    base = _versions(rig, mid)[0]
    b = base["fit"]["budget"]  # kept with the version: floor, its sensor part, what is left
    assert b["floor_deg"] > 0 and b["left_deg"] > 0 and not b["at_floor"]
    assert b["rms_deg"] ** 2 == pytest.approx(b["floor_deg"] ** 2 + b["left_deg"] ** 2, rel=1e-6)

    # the same log on disk, written differently (CRLF, other float formatting): found by its data
    meas = parse_log(offset_csv, "x")
    csv = tmp_path / "from-the-rig.csv"
    csv.write_text(
        "t,u,theta\r\n"
        + "".join(
            f"{float(t)!r},{float(u)!r},{float(th)!r}\r\n"
            for t, u, th in zip(meas.t_s, meas.u_v, meas.theta_rad, strict=True)
        )
    )
    assert main(["model", "history", str(csv), "--db", str(db), "--replicas", "0", "--json"]) == 0
    hist = json.loads(capsys.readouterr().out)
    assert [v["change"] for v in hist["versions"]] == ["base"]
    assert hist["versions"][0]["rms_deg"] == pytest.approx(base["fit"]["rms_deg"])
    assert hist["versions"][0]["budget"]["floor_deg"] == pytest.approx(b["floor_deg"])

    # a fit from the command line lands in the console's database: the console lists it
    assert main(["model", "fit", str(csv), "--axis", "pan", "--effects", "offset", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert f"kept as version 2 (+offset) of measurement #{mid}" in out
    vs = _versions(rig, mid)
    assert [v["label"] for v in vs] == ["base", "+offset"]
    assert vs[1]["parent_id"] == vs[0]["id"] and vs[1]["model"]["axis"] == "pan"
    nb = vs[1]["fit"]["budget"]
    assert [e["change"] for e in nb["explained"]] == ["+offset"]
    assert vs[1]["fit"]["rms_deg"] < 0.5 * vs[0]["fit"]["rms_deg"]
    explained = nb["explained"][0]["deg"]
    assert explained**2 == pytest.approx(b["rms_deg"] ** 2 - nb["rms_deg"] ** 2, rel=1e-6)
    assert nb["left_deg"] < 0.5 * b["left_deg"]  # most of what was left, the effect explained
    # ... and the console works on it like on its own versions
    cmp = rig.client.post(
        f"{API}/measurements/{mid}/compare", headers=rig.h("viewer"), json={"version_id": vs[1]["id"]}
    )
    assert cmp.status_code == 200, cmp.text
    measured = cmp.json()["residual_verdict"]["rms_rad"]["measured"]
    assert math.degrees(measured) == pytest.approx(nb["rms_deg"], rel=1e-9)  # the same figures
    # the console's next version counts the CLI's in its budget
    add = rig.client.post(
        f"{API}/measurements/{mid}/add-effect", headers=rig.h("engineer"), json={"effect": "gravity"}
    )
    assert add.status_code == 201, add.text
    assert [e["change"] for e in add.json()["fit"]["budget"]["explained"]] == ["+offset", "+gravity"]

    # history by measurement number (the log read from the database), with its picture
    png = tmp_path / "history.png"
    assert main(["model", "history", "--db", str(db), "--measurement", str(mid), "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "3 version(s)" in text and "+gravity" in text and "explained by +offset" in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    with sqlite3.connect(db) as c:
        assert c.execute("PRAGMA integrity_check").fetchone()[0] == "ok"


def test_a_new_log_from_the_cli_becomes_a_console_measurement(
    rig: Rig, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = rig.data_dir / "console.sqlite3"
    csv = tmp_path / "bench-run.csv"
    csv.write_text(
        format_log(generate_measurement(random_hidden_model("tilt", [], seed=4), duration_s=6.0, seed=2))
    )
    before = {m["id"] for m in rig.client.get(f"{API}/measurements", headers=rig.h("viewer")).json()}
    assert main(["model", "fit", str(csv), "--axis", "tilt", "--db", str(db), "--replicas", "0"]) == 0
    capsys.readouterr()
    after = rig.client.get(f"{API}/measurements", headers=rig.h("viewer")).json()
    new = [m for m in after if m["id"] not in before]
    assert [(m["name"], m["axis"]) for m in new] == [("bench-run.csv", "tilt")]
    vs = _versions(rig, new[0]["id"])
    assert [v["label"] for v in vs] == ["base"] and "budget" not in vs[0]["fit"]  # --replicas 0
    series = rig.client.get(f"{API}/measurements/{new[0]['id']}", headers=rig.h("viewer"))
    assert series.status_code == 200  # the console reads the CSV the command line stored


def test_bad_databases_are_refused_and_a_failed_write_changes_nothing(
    rig: Rig, offset_csv: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    csv = tmp_path / "run.csv"
    csv.write_text(offset_csv)
    junk = tmp_path / "junk.sqlite3"
    junk.write_bytes(b"this is not a database" * 100)
    other = tmp_path / "other.sqlite3"
    sqlite3.connect(other).execute("CREATE TABLE x (a)").connection.close()
    for path, words in (
        (tmp_path / "none.sqlite3", "no such file"),
        (junk, "not an SQLite"),
        (other, "not the console"),
    ):
        assert main(["model", "history", str(csv), "--db", str(path)]) == 2
        err = capsys.readouterr().err
        assert words in err and str(path) in err
    # a copy of the app's database; a write that fails half-way is rolled back whole
    copy = tmp_path / "copy.sqlite3"
    with sqlite3.connect(rig.data_dir / "console.sqlite3") as src, sqlite3.connect(copy) as dst:
        src.backup(dst)
    meas = parse_log(offset_csv, "run.csv")
    new_log = Measurement(meas.t_s, meas.u_v, meas.theta_rad + 1.0, "new.csv")  # not in the database

    def counts() -> tuple[int, int]:
        with sqlite3.connect(copy) as c:
            return c.execute(
                "SELECT (SELECT COUNT(*) FROM measurements), (SELECT COUNT(*) FROM model_versions)"
            ).fetchone()

    before = counts()
    with ConsoleDatabase(copy) as cdb:
        v = cdb.history(cdb.measurements()[0].id)[0].latest
        # the measurement row goes in, then the version's insert fails: both must be undone
        cdb._conn.execute(
            "CREATE TEMP TRIGGER fail BEFORE INSERT ON model_versions "
            "BEGIN SELECT RAISE(ABORT, 'disk full'); END"
        )
        with pytest.raises(sqlite3.DatabaseError, match="disk full"):
            cdb.append(new_log, offset_csv, "new.csv", "pan", v)
    assert counts() == before
    with sqlite3.connect(copy) as c:
        assert c.execute("PRAGMA integrity_check").fetchone()[0] == "ok"


def test_the_cli_reproduces_the_consoles_history_from_the_same_data(
    offset_csv: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The console's steps (app/heavy.py, as its workers run them) and the command line's on the
    same log give the same versions: labels, errors, budgets."""
    from app import heavy

    first = heavy.first_version("run.csv", "pan", offset_csv)
    b1 = first["fit"]["budget"]
    added = heavy.refit(
        offset_csv, "run.csv", "pan", first["model"], None, "offset", "+offset", [("base", b1["rms_deg"])]
    )
    console = [first["fit"], added["fit"]]

    csv = tmp_path / "run.csv"
    csv.write_text(offset_csv)
    ws = str(tmp_path / "ws")
    assert main(["model", "fit", str(csv), "--axis", "pan", "--workspace", ws]) == 0
    assert main(["model", "fit", str(csv), "--axis", "pan", "--effects", "offset", "--workspace", ws]) == 0
    capsys.readouterr()
    png = tmp_path / "h.png"
    assert main(["model", "history", str(csv), "--workspace", ws, "--json", "--plot", str(png)]) == 0
    cli = json.loads(capsys.readouterr().out.splitlines()[0])["versions"]
    assert [v["change"] for v in cli] == ["base", "+offset"]
    for c, k in zip(console, cli, strict=True):
        assert k["rms_deg"] == pytest.approx(c["rms_deg"], rel=1e-6)
        assert k["fit_percent"] == pytest.approx(c["fit_percent"], abs=1e-6)
        for key in ("rms_deg", "floor_deg", "left_deg", "quantization_deg"):
            assert k["budget"][key] == pytest.approx(c["budget"][key], rel=1e-6, abs=1e-9), key
    assert [e["change"] for e in cli[1]["budget"]["explained"]] == ["+offset"]
    assert [v["budget"]["at_floor"] for v in cli] == [c["budget"]["at_floor"] for c in console]
    assert not cli[0]["budget"]["at_floor"]
    assert png.stat().st_size > 20_000
