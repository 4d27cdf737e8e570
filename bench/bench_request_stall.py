"""Benchmark: how long hostile or heavy requests stall the engine of a real ``tracker serve``.

Starts the service on 127.0.0.1 (a free port, a temporary data folder, no audio, no 3D view),
follows the telemetry WebSocket and, for each scenario, reports the largest gap between two
telemetry frames while the request ran (the engine's stall: frames come every 10 ms when it
keeps up), how far the engine fell behind the wall clock, the server's resident memory
before and after, and the response's status, size and time.

    PYTHONPATH=. .venv/bin/python bench/bench_request_stall.py              # bodies only (~1 min)
    PYTHONPATH=. .venv/bin/python bench/bench_request_stall.py --compare-rows 1000000

Scenarios: a 10 MB and a 50 MB body that is valid JSON but invalid for the schema (a viewer's
gain preview whose ``gains`` hold strings), the same at 60 kB (just under ``max_body_bytes``),
a 10 MB body that is not JSON, a 50 MB body sent
with no key, 2000 bad keys in a row; with ``--compare-rows``, four parallel ``compare`` calls by
a viewer on a measurement of that many rows (put straight into the database, as one stored
before any row cap).
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
from websockets.sync.client import connect

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


class Frames:
    """Telemetry frames as (wall time, engine time), from a background thread; a socket the
    server closed (its keep-alive ping times out during a long stall) is opened again."""

    def __init__(self, url: str, key: str) -> None:
        self.rows: list[tuple[float, float]] = []
        self.reconnects = 0
        self._url, self._key = url, key
        self._stop = threading.Event()
        self._ws = self._connect()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _connect(self):  # type: ignore[no-untyped-def]
        ws = connect(self._url, max_size=None, open_timeout=120, ping_interval=None)
        ws.send(json.dumps({"key": self._key}))
        return ws

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                msg = json.loads(self._ws.recv(timeout=120))
            except Exception:
                if self._stop.is_set():
                    return
                try:
                    self._ws = self._connect()
                    self.reconnects += 1
                except Exception:
                    time.sleep(0.5)
                continue
            if msg.get("type") == "frame":
                self.rows.append((time.perf_counter(), float(msg["t_s"])))

    def window(self, t0: float, t1: float) -> tuple[float, float]:
        """Largest gap between frames (s) and the largest lag behind the wall clock (s) in [t0, t1]."""
        rows = [r for r in self.rows if t0 - 0.2 <= r[0] <= t1 + 0.5]
        if len(rows) < 2:
            return float("nan"), float("nan")
        gap = max(b[0] - a[0] for a, b in zip(rows, rows[1:], strict=False))
        w0, e0 = rows[0]
        lag = max((w - w0) - (e - e0) for w, e in rows)
        return gap, lag

    def close(self) -> None:
        self._stop.set()
        self._ws.close()


def scenario(name: str, frames: Frames, pid: int, fn) -> None:  # type: ignore[no-untyped-def]
    time.sleep(0.5)
    rss0 = rss_mb(pid)
    t0 = time.perf_counter()
    try:
        status, size = fn()
    except Exception as exc:  # a reset connection is a finding too
        status, size = f"{type(exc).__name__}", 0
    t1 = time.perf_counter()
    time.sleep(0.6)
    gap, lag = frames.window(t0, t1)
    print(
        f"{name:44s} status {status!s:>14s}  reply {size / 1e3:9.1f} kB  took {t1 - t0:6.2f} s  "
        f"largest frame gap {gap * 1e3:7.0f} ms  lag {lag:6.2f} s  RSS {rss0:6.0f} -> {rss_mb(pid):6.0f} MB",
        flush=True,
    )


def post(client: httpx.Client, path: str, body: bytes, key: str | None) -> tuple[int, int]:
    headers = {"Content-Type": "application/json"}
    if key:
        headers["X-API-Key"] = key
    r = client.post(path, content=body, headers=headers)
    return r.status_code, len(r.content)


def strings_body(size: int) -> bytes:
    n = size // 18  # each entry is 18 bytes: "k00000000": "x", 
    return json.dumps({"gains": {f"k{i:08d}": "x" for i in range(n)}}).encode()


def put_measurement(db: Path, rows: int, src_mid: int) -> int:
    """Copy measurement ``src_mid``'s latest version onto a new measurement of ``rows`` rows."""
    csv = "t,u,theta\n" + "".join(f"{k * 1e-3:.3f},0.1,{(k % 1000) * 1e-4:.4f}\n" for k in range(rows))
    con = sqlite3.connect(db, timeout=30)
    with con:
        cur = con.execute(
            "INSERT INTO measurements (name, axis, csv, n, dt_s, created_s) "
            "VALUES (?, 'pan', ?, ?, 0.001, ?)",
            (f"big {rows}", csv, rows, time.time()),
        )
        mid = int(cur.lastrowid or 0)
        model, fit = con.execute(
            "SELECT model, fit FROM model_versions WHERE measurement_id = ? ORDER BY id DESC", (src_mid,)
        ).fetchone()
        con.execute(
            "INSERT INTO model_versions (measurement_id, parent_id, label, model, fit, created_s) "
            "VALUES (?, NULL, 'base', ?, ?, ?)",
            (mid, model, fit, time.time()),
        )
    con.close()
    return mid


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--compare-rows", type=int, default=0, help="rows of the measurement for 4 compares")
    ap.add_argument("--skip-bodies", action="store_true")
    args = ap.parse_args()
    port = free_port()
    data = Path(tempfile.mkdtemp(prefix="stall-"))
    env = dict(
        os.environ,
        PYTHONPATH=str(ROOT),
        TRACKER_DATA_DIR=str(data),
        TRACKER_AUDIO_ENABLED="false",
        TRACKER_VIEWER_ENABLED="false",
        TRACKER_LOG_LEVEL="warning",
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", "tracker", "serve", "--host", "127.0.0.1", "--port", str(port)],
        env=env,
        cwd=data,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        with httpx.Client(base_url=base + "/api/v1", timeout=300) as c:
            deadline = time.monotonic() + 60
            while True:
                try:
                    if c.get("/health").status_code == 200:
                        break
                except httpx.TransportError:
                    pass
                if time.monotonic() > deadline or proc.poll() is not None:
                    print("the service did not start", file=sys.stderr)
                    return 1
                time.sleep(0.2)
            admin = (data / "admin.key").read_text().strip()
            ah = {"X-API-Key": admin}
            viewer = c.post("/keys", headers=ah, json={"name": "bench viewer", "role": "viewer"}).json()[
                "key"
            ]
            frames = Frames(f"ws://127.0.0.1:{port}/api/v1/telemetry", viewer)
            time.sleep(1.0)
            scenario("idle (no request)", frames, proc.pid, lambda: (0, 0))
            preview = "/axes/pan/gains/preview"
            if not args.skip_bodies:
                for mb in (10, 50):
                    body = strings_body(mb * 1_000_000)
                    scenario(
                        f"{mb} MB schema-invalid JSON, viewer",
                        frames,
                        proc.pid,
                        lambda b=body: post(c, preview, b, viewer),
                    )
                body = strings_body(60_000)
                scenario("60 kB schema-invalid JSON (under the cap)", frames, proc.pid,
                         lambda b=body: post(c, preview, b, viewer))
                garbage = b"{" + b"x" * 10_000_000
                scenario(
                    "10 MB non-JSON body, viewer", frames, proc.pid, lambda: post(c, preview, garbage, viewer)
                )
                body = strings_body(50_000_000)
                scenario("50 MB body, no key", frames, proc.pid, lambda: post(c, preview, body, None))

                def bad_keys() -> tuple[str, int]:
                    codes: dict[int, int] = {}
                    for i in range(2000):
                        code = c.get("/status", headers={"X-API-Key": f"3dat_bad{i}"}).status_code
                        codes[code] = codes.get(code, 0) + 1
                    return "/".join(f"{k}x{v}" for k, v in sorted(codes.items())), 0

                scenario("2000 bad keys in a row", frames, proc.pid, bad_keys)
            if args.compare_rows:
                from tracker.workbench.experiments.experiments import (
                    generate_measurement,
                    random_hidden_model,
                )
                from tracker.workbench.measurements.data import format_log

                small = format_log(generate_measurement(random_hidden_model("pan", ["offset"], 1), 5.0, 1))
                eh = {
                    "X-API-Key": c.post(
                        "/keys", headers=ah, json={"name": "bench eng", "role": "engineer"}
                    ).json()["key"]
                }
                r = c.post(
                    "/workbench/measurements",
                    headers=eh,
                    files={"file": ("s.csv", small.encode(), "text/csv")},
                    data={"axis": "pan"},
                )
                mid = put_measurement(data / "console.sqlite3", args.compare_rows, int(r.json()["id"]))

                def four() -> tuple[str, int]:
                    with ThreadPoolExecutor(4) as pool:
                        rs = list(
                            pool.map(
                                lambda _: c.post(
                                    f"/workbench/measurements/{mid}/compare",
                                    headers={"X-API-Key": viewer},
                                    json={},
                                ),
                                range(4),
                            )
                        )
                    return "/".join(str(x.status_code) for x in rs), sum(len(x.content) for x in rs)

                scenario(f"4 parallel compares, {args.compare_rows} rows", frames, proc.pid, four)
            frames.close()
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
