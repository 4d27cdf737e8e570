"""Read deploy/3dat-console.service and turn its start into a command for a test sandbox."""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
UNIT = ROOT / "deploy" / "3dat-console.service"
DOCKERFILE = ROOT / "deploy" / "Dockerfile"


@dataclass(frozen=True, slots=True)
class UnitStart:
    """What systemd runs: the command, the environment it sets, its folders."""

    exec_start: list[str]
    environment: dict[str, str]
    environment_files: list[str]
    working_directory: str
    state_directory: str
    read_write_paths: list[str]
    service: dict[str, list[str]]


def parse_unit(path: Path = UNIT) -> UnitStart:
    """The ``[Service]`` section of a unit (keys may repeat; values kept in order)."""
    section = ""
    service: dict[str, list[str]] = {}
    for raw in path.read_text(encoding="utf-8").splitlines():
        line = raw.strip()
        if not line or line.startswith(("#", ";")):
            continue
        if line.startswith("["):
            section = line.strip("[]")
            continue
        if section == "Service":
            key, _, value = line.partition("=")
            service.setdefault(key.strip(), []).append(value.strip())
    env: dict[str, str] = {}
    for value in service.get("Environment", []):
        for item in shlex.split(value):
            name, _, val = item.partition("=")
            env[name] = val
    (state,) = service["StateDirectory"]
    return UnitStart(
        exec_start=shlex.split(service["ExecStart"][-1]),
        environment=env,
        environment_files=[v.lstrip("-") for v in service.get("EnvironmentFile", [])],
        working_directory=service["WorkingDirectory"][-1],
        state_directory="/var/lib/" + state,
        read_write_paths=[p for v in service.get("ReadWritePaths", []) for p in v.split()],
        service=service,
    )


def relocate(text: str, places: dict[str, Path]) -> str:
    """``text`` with each of the unit's folders replaced by the test's stand-in for it."""
    for original in sorted(places, key=len, reverse=True):
        text = text.replace(original, str(places[original]))
    return text
