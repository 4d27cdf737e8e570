"""Limits (issue #11 item 2): what one request may cost. Keys and sizes are checked before a body
is read, 422s do not echo big inputs, measurements have a row cap, heavy work runs in a bounded
pool of worker processes with a cap per key, and bad keys from one address get 429."""

from __future__ import annotations

import asyncio
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from starlette.websockets import WebSocketDisconnect

from app.auth import Principal, Role
from app.backoff import BadKeyBackoff
from app.errors import TooManyRequests
from app.work import WorkPool

from .conftest import Rig, make_rig

API = "/api/v1"
MB = 1_000_000


@pytest.fixture(scope="module")
def tight(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    """A service with small limits: 3 bad keys, 2000 rows, one heavy request per key, no queue."""
    yield from make_rig(
        tmp_path_factory.mktemp("tight"),
        bad_key_limit=3,
        max_measurement_rows=2000,
        heavy_per_key=1,
        heavy_queue=0,
    )


def csv_rows(n: int) -> str:
    return "t,u,theta\n" + "".join(
        f"{k * 1e-3:.3f},{0.5 * (k // 300 % 2):.1f},{k * 1e-5:.6f}\n" for k in range(n)
    )


async def _raw(
    app: Any, method: str, path: str, headers: dict[str, str], chunks: Iterator[bytes]
) -> dict[str, Any]:
    """Send one request straight to the ASGI app; how many body bytes the app pulled, and the answer."""
    pulled = 0
    answer: dict[str, Any] = {"status": None, "body": b"", "headers": {}}

    async def receive() -> dict[str, Any]:
        nonlocal pulled
        chunk = next(chunks, None)
        if chunk is None:
            return {"type": "http.request", "body": b"", "more_body": False}
        pulled += len(chunk)
        return {"type": "http.request", "body": chunk, "more_body": True}

    async def send(message: dict[str, Any]) -> None:
        if message["type"] == "http.response.start":
            answer["status"] = message["status"]
            answer["headers"] = {k.decode(): v.decode() for k, v in message["headers"]}
        elif message["type"] == "http.response.body":
            answer["body"] += message.get("body", b"")

    scope = {
        "type": "http",
        "asgi": {"version": "3.0"},
        "http_version": "1.1",
        "method": method,
        "scheme": "http",
        "path": path,
        "raw_path": path.encode(),
        "query_string": b"",
        "root_path": "",
        "headers": [(k.lower().encode(), v.encode()) for k, v in headers.items()],
        "client": ("127.0.0.9", 40000),
        "server": ("testserver", 80),
        "state": {},
    }
    await app(scope, receive, send)
    return {**answer, "pulled": pulled, "json": json.loads(answer["body"] or b"null")}


def raw(
    rig: Rig,
    method: str,
    path: str,
    headers: dict[str, str],
    total: int,
    chunk: int = MB,
    length: bool = True,
) -> dict[str, Any]:
    """``total`` bytes of body in ``chunk``-byte pieces (with a Content-Length header when ``length``)."""
    if length:
        headers = {**headers, "Content-Length": str(total)}
    head = FILE_PART if "multipart" in headers.get("Content-Type", "") else b""
    chunks = iter([head, *[b"x" * chunk] * (total // chunk)])
    return rig.client.portal.call(_raw, rig.client.app, method, API + path, headers, chunks)  # type: ignore[union-attr]


UPLOAD = "/workbench/measurements"
FILE_PART = b'--b0undary\r\nContent-Disposition: form-data; name="file"; filename="a.csv"\r\n\r\n'
MULTIPART = {"Content-Type": "multipart/form-data; boundary=b0undary"}
JSON = {"Content-Type": "application/json"}


@pytest.mark.parametrize(
    ("who", "path", "ctype", "status"),
    [
        (None, "/axes/pan/gains/preview", JSON, 401),
        ("3dat_not-a-key", "/axes/pan/gains/preview", JSON, 401),
        (None, UPLOAD, MULTIPART, 401),
        ("viewer", UPLOAD, MULTIPART, 403),
    ],
    ids=["no-key-json", "bad-key-json", "no-key-upload", "viewer-upload"],
)
def test_no_valid_key_means_the_body_is_never_read(
    rig: Rig, who: str | None, path: str, ctype: dict[str, str], status: int
) -> None:
    """Bug: 50 MB with no key cost 2.1 s and +280 MB before the 401; a 212 MB upload was read in
    full before the 401/403. The guard answers from the headers alone."""
    key = rig.keys.get(who or "", who)
    headers = {**ctype, **({"X-API-Key": key} if key else {})}
    r = raw(rig, "POST", path, headers, total=50 * MB)
    assert r["status"] == status and r["pulled"] == 0, r["json"]
    assert r["json"]["error"] in ("Unauthorized", "Forbidden")


def test_an_upload_over_the_limit_is_refused_before_it_is_read(rig: Rig) -> None:
    """Bug: a 212 MB upload was read in full (the route's own check ran after FastAPI read it)."""
    r = raw(rig, "POST", UPLOAD, {**MULTIPART, **rig.h("engineer")}, total=212 * MB, chunk=4 * MB)
    assert r["status"] == 413 and r["pulled"] == 0
    assert r["json"]["setting"] == "max_upload_bytes" and "max_upload_bytes" in r["json"]["detail"]


@pytest.mark.parametrize(("path", "status"), [("/workbench/measurement", 404),
                                            ("/workbench/measurements/upload", 405)])  # a GET route
def test_an_upload_to_a_wrong_path_is_404_not_413_and_is_not_read(rig: Rig, path: str, status: int) -> None:
    """Bug: a 1 MB upload to a mistyped path got 413 'a request body may have at most 65536
    bytes': the body limit of a route-less request was checked before the router said 404."""
    r = raw(rig, "POST", path, {**MULTIPART, **rig.h("engineer")}, total=MB)
    assert r["status"] == status and r["pulled"] == 0, r["json"]
    r = raw(rig, "POST", UPLOAD, {**MULTIPART, **rig.h("engineer")}, total=212 * MB)
    assert r["status"] == 413 and r["pulled"] == 0  # the right path keeps its limit


@pytest.mark.parametrize(
    ("path", "ctype", "limit"),
    [("/axes/pan/gains/preview", JSON, 65_536), (UPLOAD, MULTIPART, 20 * MB)],
    ids=["json", "upload"],
)
def test_a_body_streamed_past_the_limit_is_cut_off(
    rig: Rig, path: str, ctype: dict[str, str], limit: int
) -> None:
    """Bug: no body limit. Without a Content-Length the guard counts and stops at the limit."""
    r = raw(
        rig, "POST", path, {**ctype, **rig.h("engineer")}, total=limit + 50 * MB, chunk=MB // 4, length=False
    )
    assert r["status"] == 413, r["json"]
    assert limit < r["pulled"] <= limit + MB // 4 + len(FILE_PART)
    assert r["json"]["error"] == "TooLarge" and r["json"]["limit_bytes"] == limit


def test_a_422_does_not_echo_a_big_body(rig: Rig) -> None:
    """Bug: a 10 MB invalid body from a viewer came back as a 92 MB 422 (every input echoed) and
    froze the engine for 18 s. Now the body is capped at 64 kB and the 422 lists a few errors."""
    body = json.dumps({"gains": {f"k{i:07d}": "x" * 20 for i in range(1700)}}).encode()
    assert 50_000 < len(body) <= 65_536
    r = rig.client.post(f"{API}/axes/pan/gains/preview", headers={**rig.h("viewer"), **JSON}, content=body)
    assert r.status_code == 422
    assert len(r.content) < 10_000
    out = r.json()
    assert out["error"] == "ValidationError" and isinstance(out["detail"], str)
    assert out["errors_total"] >= 1700 and len(out["errors"]) == 20
    assert "gains.k0000000" in out["detail"]


def test_a_long_string_is_shortened_in_the_422(rig: Rig) -> None:
    """Bug: the 422 echoed its input whole."""
    r = rig.client.put(
        f"{API}/pointing", headers=rig.h("operator"), json={"pan_deg": "9" * 60_000, "tilt_deg": 0}
    )
    assert r.status_code == 422 and len(r.content) < 2_000
    assert "60000 characters" in r.json()["errors"][0]["input"]


def test_a_measurement_over_the_row_cap_is_413_naming_the_cap(tight: Rig) -> None:
    """Bug: no cap on rows; a 10^6-row measurement made every compare cost seconds of engine time."""
    before = tight.client.get(f"{API}/workbench/measurements", headers=tight.h("viewer")).json()
    r = tight.client.post(
        f"{API}{UPLOAD}",
        headers=tight.h("engineer"),
        files={"file": ("big.csv", csv_rows(2001).encode(), "text/csv")},
        data={"axis": "pan"},
    )
    assert r.status_code == 413, r.text
    assert r.json()["limit_rows"] == 2000 and "max_measurement_rows" in r.json()["detail"]
    assert tight.client.get(f"{API}/workbench/measurements", headers=tight.h("viewer")).json() == before


def _principal(key_id: int) -> Principal:
    return Principal(key_id, f"key {key_id}", Role.viewer)


def test_heavy_work_runs_in_another_process() -> None:
    """Bug: compares ran in threads of the engine's process; their numba kernels hold the
    interpreter lock, so four of them put the engine 15.5 s behind real time."""

    async def pid() -> int:
        pool = WorkPool(workers=1)
        try:
            return await pool.run(_principal(1), os.getpid)
        finally:
            pool.close()

    assert asyncio.run(pid()) != os.getpid()


def test_heavy_work_runs_nicer_than_the_service() -> None:
    """Issue 10 item 6: the workbench's diagnoses ran at the service's own niceness, competing
    on equal terms with the web side (whose interpreter lock the control loop waits for)."""
    from app.work import worker_niceness
    from app.workers import WORKER_NICE

    async def nice() -> int:
        pool = WorkPool(workers=1)
        try:
            return await pool.run(_principal(1), worker_niceness)
        finally:
            pool.close()

    assert asyncio.run(nice()) == min(19, os.nice(0) + WORKER_NICE)


def test_heavy_work_knows_the_sites_own_effects() -> None:
    """A worker is a fresh process: the effects setting's plug-ins must be loaded there too."""
    cable = Path(__file__).resolve().parents[2] / "examples" / "effects" / "cable_drag.py"

    from tracker.plant.effects import optional_effects

    async def names() -> tuple[str, ...]:
        pool = WorkPool(workers=1, effects=str(cable))
        try:
            return await pool.run(_principal(1), optional_effects)
        finally:
            pool.close()

    assert asyncio.run(names())[-1] == "cable_drag"


async def test_heavy_work_is_capped_per_key_and_in_total() -> None:
    """Bug: no cap on concurrent work; now 429 with a Retry-After past the caps."""
    pool = WorkPool(workers=1, queue=1, per_key=1)
    try:
        first = asyncio.ensure_future(pool.run(_principal(1), time.sleep, 0.5))
        await asyncio.sleep(0)
        with pytest.raises(TooManyRequests, match="heavy_per_key") as per_key:
            await pool.run(_principal(1), time.sleep, 0.0)
        assert per_key.value.retry_after_s >= 1
        second = asyncio.ensure_future(pool.run(_principal(2), time.sleep, 0.0))  # waits in the queue
        await asyncio.sleep(0)
        with pytest.raises(TooManyRequests, match="heavy_queue"):
            await pool.run(_principal(3), time.sleep, 0.0)
        await asyncio.gather(first, second)
        assert pool.admitted == 0
        await pool.run(_principal(1), time.sleep, 0.0)  # free again
    finally:
        pool.close()


def test_a_second_compare_by_the_same_key_is_429_with_retry_after(tight: Rig) -> None:
    """Bug: four parallel compares by one viewer all ran; now the key's second one waits its turn."""
    up = tight.client.post(
        f"{API}{UPLOAD}",
        headers=tight.h("engineer"),
        files={"file": ("small.csv", csv_rows(1500).encode(), "text/csv")},
        data={"axis": "pan"},
    )
    assert up.status_code == 201, up.text
    svc = tight.client.app.state.svc  # type: ignore[attr-defined]
    viewer = tight.client.get(f"{API}/whoami", headers=tight.h("viewer")).json()
    busy = tight.client.portal.start_task_soon(  # type: ignore[union-attr]
        svc.work.run, Principal(viewer["key_id"], viewer["name"], Role.viewer), time.sleep, 1.0
    )
    r = tight.client.post(
        f"{API}/workbench/measurements/{up.json()['id']}/compare", headers=tight.h("viewer"), json={}
    )
    busy.result(timeout=30)
    assert r.status_code == 429 and int(r.headers["Retry-After"]) >= 1
    assert r.json()["error"] == "TooManyRequests" and "heavy_per_key" in r.json()["detail"]
    again = tight.client.post(
        f"{API}/workbench/measurements/{up.json()['id']}/compare", headers=tight.h("viewer"), json={}
    )
    assert again.status_code == 200, again.text


def test_bad_keys_from_one_address_get_429_with_retry_after(tight: Rig) -> None:
    """Bug: 2000 bad keys at 125/s, never a 429. After bad_key_limit (3 here) the address waits;
    a valid key from the same address still works, and WebSockets are refused too (4429)."""
    codes = [tight.client.get(f"{API}/status", headers={"X-API-Key": f"3dat_bad{i}"}) for i in range(5)]
    assert [r.status_code for r in codes] == [401, 401, 401, 429, 429]
    assert int(codes[3].headers["Retry-After"]) >= 1 and codes[3].json()["error"] == "TooManyRequests"
    assert tight.client.get(f"{API}/status", headers=tight.h("viewer")).status_code == 200
    with tight.client.websocket_connect(f"{API}/telemetry") as ws:
        ws.send_text(json.dumps({"key": "3dat_bad-ws"}))
        with pytest.raises(WebSocketDisconnect) as closed:
            ws.receive_json()
    assert closed.value.code == 4429


def test_the_back_off_doubles_and_forgets_after_a_quiet_spell() -> None:
    now = [0.0]
    b = BadKeyBackoff(limit=2, window_s=10.0, max_block_s=60.0, clock=lambda: now[0])
    assert [b.failed("a"), b.failed("a")] == [0.0, 0.0]
    assert b.failed("a") == pytest.approx(5.0)  # third bad key: blocked 5 s
    assert b.failed("b") == 0.0  # other addresses are not affected
    now[0] = 5.1
    assert b.retry_after_s("a") == 0.0
    b.failed("a"), b.failed("a")
    assert b.failed("a") == pytest.approx(10.0)  # the next block doubles
    now[0] = 200.0  # quiet for longer than max_block_s
    b.failed("a"), b.failed("a")
    assert b.failed("a") == pytest.approx(5.0)


def test_limits_are_settings(tmp_path: Path) -> None:
    from app.settings import load_settings

    s = load_settings(None, data_dir=str(tmp_path))
    assert (s.max_body_bytes, s.max_upload_bytes, s.max_measurement_rows) == (65_536, 20 * MB, 250_000)
    assert (s.heavy_workers, s.heavy_queue, s.heavy_per_key, s.bad_key_limit) == (1, 4, 2, 10)


def _until_cancelled(progress: Any, cancel: Any) -> dict[str, Any]:
    """A job (run in a worker process) that waits until it is cancelled."""
    end = time.monotonic() + 30.0
    while not cancel() and time.monotonic() < end:
        time.sleep(0.01)
    return {"ok": True}


async def test_jobs_are_capped(tmp_path: Path) -> None:
    """Bug: no cap on concurrent work; friction-ID jobs each took a thread without limit."""
    from app.db import Database
    from app.jobs import JobRunner
    from app.workers import WorkerPool

    pool = WorkerPool(1)
    runner = JobRunner(Database(tmp_path / "jobs.sqlite3"), pool, max_running=2)
    try:
        ids = [runner.start("wait", {}, _until_cancelled) for _ in range(2)]
        with pytest.raises(TooManyRequests, match="max_running_jobs"):
            runner.start("wait", {}, _until_cancelled)
        for job_id in ids:
            runner.cancel(job_id)
        for job_id in ids:
            await runner.wait(job_id)
        assert [runner.db.get_job(i)["state"] for i in ids] == ["cancelled", "cancelled"]  # type: ignore[index]
        job_id = runner.start("wait", {}, _until_cancelled)  # room again
        runner.cancel(job_id)
        await runner.wait(job_id)
    finally:
        await runner.shutdown()
        pool.shutdown()
