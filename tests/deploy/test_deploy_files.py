"""The deploy files agree with each other and with the install: the unit's ExecStart is what
``dev.py install`` makes, its caches live in its state folder, the container runs the same
install, and the wheel carries every file of static/ and examples/."""

from __future__ import annotations

import importlib.util
import re
import shlex
import shutil
import subprocess
import tomllib
from pathlib import Path

import pytest

from tests.deploy.unit_file import DOCKERFILE, ROOT, UNIT, parse_unit, relocate


def _dev() -> object:
    spec = importlib.util.spec_from_file_location("dev_script", ROOT / "dev.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_unit_runs_what_dev_py_install_installs() -> None:
    unit = parse_unit()
    prefix = _dev().DEFAULT_PREFIX  # type: ignore[attr-defined]
    assert unit.working_directory == prefix
    assert unit.exec_start[:2] == [f"{prefix}/.venv/bin/tracker", "serve"]
    config = unit.exec_start[unit.exec_start.index("--config") + 1]
    assert config == "/etc/3dat/console.toml"


def test_the_unit_writes_only_its_state_folder() -> None:
    unit = parse_unit()
    service = unit.service
    assert service["ProtectSystem"] == ["strict"] and service["PrivateTmp"] == ["yes"]
    assert service["ProtectHome"] == ["yes"]
    assert all(Path(p).is_relative_to(unit.state_directory) for p in unit.read_write_paths)
    for name in ("NUMBA_CACHE_DIR", "MPLCONFIGDIR"):
        assert Path(unit.environment[name]).is_relative_to(unit.state_directory), name
    example = tomllib.loads((ROOT / "deploy" / "console.example.toml").read_text(encoding="utf-8"))
    assert example["data_dir"] == unit.state_directory


def test_the_start_test_relocates_every_path_of_the_unit() -> None:
    """tests/deploy/test_unit_start.py runs the unit's own ExecStart and Environment with these
    folders replaced; a new absolute path in the unit must get a stand-in there too."""
    unit = parse_unit()
    places = {"/opt/3dat": Path("/X"), unit.state_directory: Path("/X"), "/etc/3dat": Path("/X")}
    values = [*unit.exec_start, *unit.environment.values(), *unit.environment_files]
    for value in values:
        for path in re.findall(r"(/[\w./-]+)", value):
            assert relocate(path, places).startswith("/X"), f"{path} in the unit has no stand-in"


def test_systemd_accepts_the_unit(tmp_path: Path) -> None:
    if not shutil.which("systemd-analyze"):
        pytest.skip("systemd-analyze is not installed")
    unit = tmp_path / UNIT.name
    unit.write_text(UNIT.read_text(encoding="utf-8"))
    out = subprocess.run(["systemd-analyze", "verify", str(unit)], capture_output=True, text=True)
    problems = [
        line for line in (out.stdout + out.stderr).splitlines()
        if line.strip()
        and "does not match strict user/group name rules" not in line  # '3dat' starts with a digit
        # not installed on this machine:
        and not re.search(r"Command /opt/3dat/\.venv/bin/tracker is not executable", line)
    ]
    assert not problems, "\n".join(problems)


def _dockerfile_instructions() -> list[tuple[str, str]]:
    text = DOCKERFILE.read_text(encoding="utf-8").replace("\\\n", " ")
    out = []
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            word, _, rest = line.partition(" ")
            out.append((word.upper(), rest.strip()))
    return out


def test_the_container_is_made_by_the_same_install() -> None:
    steps = _dockerfile_instructions()
    runs = [rest for word, rest in steps if word == "RUN"]
    installs = [re.search(r"python3 (\S+)/dev\.py install --prefix (\S+)", r) for r in runs]
    found = [m for m in installs if m]
    assert len(found) == 1, runs
    source, prefix = found[0].group(1), found[0].group(2)
    assert prefix == _dev().DEFAULT_PREFIX  # type: ignore[attr-defined]
    assert any(word == "COPY" and rest.split()[-1] == source for word, rest in steps)
    # Nothing else installs Python packages or a browser.
    for run in runs:
        assert not re.search(r"pip3? install|dev\.py (setup|test|serve)|playwright|chromium|-e ", run), run
    cmd = next(rest for word, rest in steps if word == "CMD")
    assert cmd.startswith("[")
    assert shlex.split(cmd.strip("[]").replace(",", " "))[0] == f"{prefix}/.venv/bin/tracker"
    env = " ".join(rest for word, rest in steps if word == "ENV")
    data = re.search(r"TRACKER_DATA_DIR=(\S+)", env)
    assert data is not None
    for name in ("NUMBA_CACHE_DIR", "MPLCONFIGDIR"):
        value = re.search(rf"{name}=(\S+)", env)
        assert value is not None and Path(value.group(1)).is_relative_to(data.group(1)), name
    assert any(word == "USER" and rest != "root" for word, rest in steps)


def test_the_docker_context_keeps_what_the_install_needs() -> None:
    ignored = (ROOT / ".dockerignore").read_text(encoding="utf-8").split()
    needs = ("pyproject.toml", "requirements.lock", "README.md", "dev.py",
             "tracker", "app", "static", "examples")
    for needed in needs:
        assert needed not in ignored


def test_the_wheel_carries_every_static_and_example_file() -> None:
    """pyproject.toml lists data-file folders one by one: a new folder must be listed too."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    data_files = config["tool"]["setuptools"]["data-files"]
    shipped: set[Path] = set()
    for target, patterns in data_files.items():
        assert target.startswith("share/3dat-console/")
        for pattern in patterns:
            for path in ROOT.glob(pattern):
                assert target == "share/3dat-console/" + str(path.parent.relative_to(ROOT))
                shipped.add(path.relative_to(ROOT))
    wanted = {
        p.relative_to(ROOT)
        for folder in ("static", "examples")
        for p in (ROOT / folder).rglob("*")
        if p.is_file() and "__pycache__" not in p.parts
    }
    assert wanted - shipped == set(), "not in the wheel: " + ", ".join(map(str, sorted(wanted - shipped)))


def test_the_wheel_carries_every_data_file_of_the_packages() -> None:
    """Files in tracker/ and app/ that are not Python reach the wheel only through package-data."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    package_data = config["tool"]["setuptools"].get("package-data", {})
    for package in ("tracker", "app"):
        listed = {p for pattern in package_data.get(package, []) for p in (ROOT / package).glob(pattern)}
        data = {
            p for p in (ROOT / package).rglob("*")
            if p.is_file() and p.suffix not in {".py", ".pyc"} and "__pycache__" not in p.parts
            and not p.name.endswith((".nbi", ".nbc"))
        }
        assert data <= listed, f"not in package-data of {package}: {sorted(map(str, data - listed))}"


def test_the_unit_allows_the_real_time_priorities_the_example_asks_for() -> None:
    """control_loop_priority (and service_threads_priority) are refused without RLIMIT_RTPRIO
    (the service is not root); the unit must allow what the example settings ask for."""
    limit = int(parse_unit().service["LimitRTPRIO"][0])
    example = tomllib.loads((ROOT / "deploy" / "console.example.toml").read_text(encoding="utf-8"))
    assert 0 < example["control_loop_priority"] <= limit
    assert example.get("service_threads_priority", 0) < example["control_loop_priority"]
