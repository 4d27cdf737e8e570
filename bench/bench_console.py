"""Telemetry fan-out of the console: frames per second each WebSocket viewer receives.

Starts the real service (uvicorn, its own process, simulated rig, no audio, no 3D view) on a
free loopback port with a temporary data folder, then connects 1, 10 and 50 viewers at once for
5 s each and prints the slowest and median viewer's rate and the largest gap between frames.

    .venv/bin/python bench/bench_console.py
"""

from __future__ import annotations

import asyncio
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import websockets

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def viewer(url: str, key: str, seconds: float) -> tuple[float, float]:
    async with websockets.connect(url, max_queue=None) as ws:
        await ws.send(json.dumps({"key": key}))
        await ws.recv()  # hello
        await ws.recv()
        t0 = time.monotonic()
        n, last, gap = 0, t0, 0.0
        while time.monotonic() - t0 < seconds:
            await ws.recv()
            now = time.monotonic()
            gap, last, n = max(gap, now - last), now, n + 1
        return n / (time.monotonic() - t0), gap


async def measure(url: str, key: str, clients: int, seconds: float = 5.0) -> None:
    results = await asyncio.gather(*(viewer(url, key, seconds) for _ in range(clients)))
    rates = sorted(r for r, _ in results)
    print(
        f"{clients:3d} viewers: slowest {rates[0]:6.1f} Hz, median {rates[len(rates) // 2]:6.1f} Hz, "
        f"largest gap {1000 * max(g for _, g in results):5.1f} ms",
        flush=True,
    )


def main() -> int:
    with tempfile.TemporaryDirectory() as data:
        port = free_port()
        env = dict(
            os.environ,
            TRACKER_DATA_DIR=data,
            TRACKER_PORT=str(port),
            TRACKER_AUDIO_ENABLED="false",
            TRACKER_VIEWER_ENABLED="false",
            TRACKER_LOG_LEVEL="warning",
        )
        proc = subprocess.Popen(
            [sys.executable, "-c", "from app.main import run_server; run_server()"],
            cwd=ROOT,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            base = f"http://127.0.0.1:{port}"
            deadline = time.monotonic() + 120
            while True:
                try:
                    if httpx.get(f"{base}/api/v1/health", timeout=2).json()["engine_running"]:
                        break
                except (httpx.HTTPError, ValueError, KeyError):
                    pass
                if time.monotonic() > deadline or proc.poll() is not None:
                    print("the service did not start", file=sys.stderr)
                    return 1
                time.sleep(0.2)
            key = (Path(data) / "admin.key").read_text().strip()
            url = f"ws://127.0.0.1:{port}/api/v1/telemetry"
            print(f"console telemetry (engine publishes one snapshot per 10 ms chunk; {os.cpu_count()} CPUs)")
            for n in (1, 10, 50):
                asyncio.run(measure(url, key, n))
        finally:
            proc.terminate()
            proc.wait(timeout=10)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
