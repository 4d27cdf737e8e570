"""The service starts the way deploy/3dat-console.service starts it: the code installed from the
wheel and read-only, a private temporary folder, the state folder the only writable place, HOME
read-only, and the unit's own ExecStart and Environment (read from the unit file, so the test
and the unit cannot drift apart)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import threading
import time
import urllib.request
from pathlib import Path

import pytest

from tests.deploy.sandbox import light_install, sandboxed
from tests.deploy.unit_file import ROOT, UnitStart, parse_unit, relocate

BANNER = re.compile(r"3DAT console: http://127\.0\.0\.1:(\d+)/")
START_TIMEOUT_S = 300.0


@pytest.fixture(scope="module")
def prefix(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An install like ``dev.py install --prefix``: TRACKER_DEPLOY_PREFIX names a real one (made
    by ``python3 dev.py install --prefix DIR``); otherwise the wheel is built and installed here
    with the dependencies borrowed from the test environment."""
    given = os.environ.get("TRACKER_DEPLOY_PREFIX")
    if given:
        return Path(given)
    base = tmp_path_factory.mktemp("opt-3dat")
    light_install(base, tmp_path_factory.mktemp("wheel"))
    return base


class Room:
    """The folders of a room computer, under a test folder: /opt/3dat, /var/lib/3dat, /etc/3dat."""

    def __init__(self, tmp: Path, prefix: Path, unit: UnitStart) -> None:
        self.unit = unit
        self.state = tmp / "var-lib-3dat"
        self.etc = tmp / "etc-3dat"
        self.private_tmp = tmp / "private-tmp"
        for d in (self.state, self.etc, self.private_tmp):
            d.mkdir()
        self.state.chmod(0o700)
        self.places = {"/opt/3dat": prefix, unit.state_directory: self.state, "/etc/3dat": self.etc}

    def configure(self, env_file: dict[str, str]) -> None:
        """deploy/console.example.toml as /etc/3dat/console.toml, and a console.env."""
        example = (ROOT / "deploy" / "console.example.toml").read_text(encoding="utf-8")
        (self.etc / "console.toml").write_text(relocate(example, self.places), encoding="utf-8")
        (self.etc / "console.env").write_text("".join(f"{k}={v}\n" for k, v in env_file.items()))

    def command(self) -> list[str]:
        return [relocate(arg, self.places) for arg in self.unit.exec_start]

    def environment(self, unit_environment: dict[str, str]) -> dict[str, str]:
        """What systemd gives the service: a bare environment, the unit's Environment= and its
        EnvironmentFile=; HOME is the service user's home (/opt/3dat, read-only)."""
        env = {
            "PATH": "/usr/local/bin:/usr/bin:/bin",
            "LANG": "C.UTF-8",
            "HOME": str(self.places["/opt/3dat"]),
            "TMPDIR": str(self.private_tmp),
        }
        env.update({k: relocate(v, self.places) for k, v in unit_environment.items()})
        for name in self.unit.environment_files:
            path = Path(relocate(name, self.places))
            if path.exists():
                for line in path.read_text().splitlines():
                    if line.strip() and not line.lstrip().startswith("#"):
                        key, _, value = line.partition("=")
                        env[key.strip()] = value.strip()
        return env


def _read_lines(proc: subprocess.Popen[str], lines: list[str]) -> None:
    assert proc.stdout is not None
    for line in proc.stdout:
        lines.append(line)


def _get(url: str, key: str | None = None) -> tuple[int, dict[str, object]]:
    req = urllib.request.Request(url, headers={"X-API-Key": key} if key else {})
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return resp.status, json.loads(resp.read())
    except urllib.error.HTTPError as exc:
        return exc.code, {}


@pytest.mark.slow
def test_the_service_starts_as_the_unit_starts_it(prefix: Path, tmp_path: Path) -> None:
    unit = parse_unit()
    room = Room(tmp_path, prefix, unit)
    # The room's own overrides, as an admin would put them in /etc/3dat/console.env: free ports,
    # and no simulated meeting (its audio takes minutes of CPU to build on first start).
    room.configure({"TRACKER_PORT": "0", "TRACKER_VIEWER_PORT": "0", "TRACKER_AUDIO_ENABLED": "false"})
    cmd, extra_env = sandboxed(room.command(), [room.state, room.private_tmp],
                               Path(relocate(unit.working_directory, room.places)), prefix)
    env = {**room.environment(unit.environment), **extra_env}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            cwd=relocate(unit.working_directory, room.places))
    lines: list[str] = []
    reader = threading.Thread(target=_read_lines, args=(proc, lines), daemon=True)
    reader.start()
    try:
        port = None
        deadline = time.monotonic() + START_TIMEOUT_S
        while port is None and time.monotonic() < deadline and proc.poll() is None:
            found = [BANNER.search(line) for line in list(lines)]
            port = next((int(m.group(1)) for m in found if m), None)
            time.sleep(0.2)
        assert port is not None, "the service did not start:\n" + "".join(lines[-40:])
        base = f"http://127.0.0.1:{port}/api/v1"
        status, health = _get(f"{base}/health")
        while status != 200 and time.monotonic() < deadline:
            time.sleep(0.5)
            status, health = _get(f"{base}/health")
        assert status == 200, health
        key = (room.state / "admin.key").read_text().strip()
        status, body = _get(f"{base}/status", key)
        assert status == 200 and "pan_deg" in body, body
        assert _get(f"{base}/status")[0] == 401
        # The console's files come from the wheel's data files (no source checkout needed).
        for page in ("/", "/static/js/app.js", "/static/vendor/uPlot.iife.min.js"):
            with urllib.request.urlopen(f"http://127.0.0.1:{port}{page}", timeout=10) as resp:
                assert resp.status == 200 and resp.read(), page
        # The compiled kernels went to the unit's NUMBA_CACHE_DIR inside the state folder.
        cache = Path(relocate(unit.environment["NUMBA_CACHE_DIR"], room.places))
        assert cache.is_relative_to(room.state)
        # (kernels compile as the loop and the workers first run them, some seconds after /health)
        cache_deadline = time.monotonic() + 90
        while not list(cache.rglob("*.nbi")) and time.monotonic() < cache_deadline:
            time.sleep(0.5)
        assert list(cache.rglob("*.nbi")), "no compiled kernel cached in " + str(cache)
    finally:
        proc.send_signal(signal.SIGTERM)  # what systemctl stop sends
        try:
            code = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
        reader.join(timeout=5)
    output = "".join(lines)
    # uvicorn shuts down cleanly, then re-raises SIGTERM; systemd counts that as a clean stop.
    assert code in (0, -signal.SIGTERM), output[-3000:]
    assert "Application shutdown complete" in output, output[-3000:]
    assert "Traceback" not in output, output[-3000:]
    assert "no locator available" not in output


@pytest.mark.parametrize(
    ("numba_env", "tmp_writable", "expected"),
    [
        ("unit", True, "env"),  # the unit's NUMBA_CACHE_DIR on the state folder
        ("none", True, "temporary"),  # no NUMBA_CACHE_DIR: this run's private temporary folder
        ("none", False, "none"),  # nothing writable at all: compiled, not cached
    ],
)
def test_kernels_compile_under_a_readonly_install(
    prefix: Path, tmp_path: Path, numba_env: str, tmp_writable: bool, expected: str
) -> None:
    """The regression: under ProtectSystem=strict with no writable cache, decorating a kernel
    raised 'cannot cache function ...: no locator available' and the service crash-looped."""
    unit = parse_unit()
    room = Room(tmp_path, prefix, unit)
    unit_env = unit.environment if numba_env == "unit" else {
        k: v for k, v in unit.environment.items() if k != "NUMBA_CACHE_DIR"
    }
    python = str(prefix / ".venv" / "bin" / "python")
    probe = (
        "import numpy as np, tracker, tracker.control.loop, tracker.plant.simulate\n"
        "from tracker.audio.localizers.tf_kernels import _reflected_window\n"  # a cached numba kernel
        "print('CHOICE', tracker.NUMBA_CACHE.kind, tracker.NUMBA_CACHE.path or '')\n"
        "print('SUM', int(_reflected_window(6, 3).sum()))\n"
    )
    writable = [room.state] + ([room.private_tmp] if tmp_writable else [])
    cwd = Path(relocate(unit.working_directory, room.places))  # read-only, as the unit's
    cmd, extra_env = sandboxed([python, "-c", probe], writable, cwd, prefix)
    env = {**room.environment(unit_env), **extra_env}
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300, cwd=cwd)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "SUM 45" in out.stdout
    if numba_env == "unit":
        assert "Matplotlib created a temporary cache directory" not in out.stderr
    kind, _, path = out.stdout.split("CHOICE ", 1)[1].splitlines()[0].partition(" ")
    assert kind == expected, out.stderr
    if expected == "env":
        assert path == relocate(unit.environment["NUMBA_CACHE_DIR"], room.places)
        assert list(Path(path).rglob("*.nbi")), "the kernel was not cached"
    elif expected == "temporary":
        assert path.startswith(str(room.private_tmp))
    else:
        assert "nothing is writable" in out.stderr
