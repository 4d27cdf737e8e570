"""Fixtures: the real server (uvicorn, its own process) on a free loopback port, and Debian's
Chromium driven by Playwright. Every test here is skipped when /usr/bin/chromium is absent."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

CHROMIUM = Path("/usr/bin/chromium")
ARGS = [
    "--no-sandbox",
    "--headless=new",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
ROOT = Path(__file__).resolve().parents[2]


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    if CHROMIUM.exists():
        return
    skip = pytest.mark.skip(reason="/usr/bin/chromium is absent (apt-get install chromium)")
    for item in items:
        if "browser" in item.keywords:
            item.add_marker(skip)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Server:
    url: str
    key: str
    data_dir: Path
    viewer_port: int

    def api(self, method: str, path: str, **kw: object) -> httpx.Response:
        return httpx.request(
            method, f"{self.url}/api/v1{path}", headers={"X-API-Key": self.key}, timeout=30, **kw
        )


@pytest.fixture(scope="package")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    if not CHROMIUM.exists():
        pytest.skip("/usr/bin/chromium is absent")
    data = tmp_path_factory.mktemp("console-data")
    port, vport = free_port(), free_port()
    env = dict(
        os.environ,
        TRACKER_DATA_DIR=str(data),
        TRACKER_PORT=str(port),
        TRACKER_HOST="127.0.0.1",
        TRACKER_VIEWER_PORT=str(vport),
        TRACKER_LOG_LEVEL="warning",
        # The simulated meeting costs ~40 s of CPU to build; app/audio.py has its own tests.
        TRACKER_AUDIO_ENABLED="false",
    )
    log = open(data / "server.log", "w")  # noqa: SIM115
    proc = subprocess.Popen(
        [sys.executable, "-c", "from app.main import run_server; run_server()"],
        cwd=ROOT,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 90
    try:
        while True:
            if proc.poll() is not None:
                raise RuntimeError(f"server exited: {(data / 'server.log').read_text()[-2000:]}")
            try:
                if httpx.get(f"{url}/api/v1/health", timeout=2).json().get("engine_running"):
                    break
            except (httpx.HTTPError, ValueError):
                pass
            if time.monotonic() > deadline:
                raise RuntimeError("server did not start in 90 s")
            time.sleep(0.2)
        yield Server(url, (data / "admin.key").read_text().strip(), data, vport)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()


@pytest.fixture(scope="package")
def browser() -> Iterator[object]:
    if not CHROMIUM.exists():
        pytest.skip("/usr/bin/chromium is absent")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser, server: Server):  # type: ignore[no-untyped-def]
    ctx = browser.new_context(viewport={"width": 1440, "height": 1000})
    pg = ctx.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto(server.url + "/")
    pg.fill("#key-input", server.key)
    pg.click("#signin-form button[type=submit]")
    pg.wait_for_selector("#main:not([hidden])")
    yield pg
    ctx.close()
    assert not errors, f"JavaScript errors on the page: {errors}"
