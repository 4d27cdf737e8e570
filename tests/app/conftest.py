"""Fixtures: the real app (engine on the simulated rig) in a TestClient, keys for each role."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.auth import Role, create_key
from app.main import create_app
from app.settings import load_settings


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Rig:
    client: TestClient
    data_dir: Path
    keys: dict[str, str]

    def h(self, role: str) -> dict[str, str]:
        return {"X-API-Key": self.keys[role]}


def make_rig(
    tmp: Path, viewer: bool = False, raise_server_exceptions: bool = True, **overrides: Any
) -> Iterator[Rig]:
    """A running service on ``tmp`` with keys for each role; ``overrides`` are settings."""
    settings = load_settings(
        None,
        **{
            "data_dir": str(tmp),
            "viewer_enabled": viewer,
            "viewer_port": free_port(),
            "audio_enabled": False,
            "control_lock_ttl_s": 30.0,
            **overrides,
        },
    )
    app = create_app(settings)
    with TestClient(app, raise_server_exceptions=raise_server_exceptions) as client:
        db = app.state.db
        keys = {"admin": (tmp / "admin.key").read_text().strip()}
        for role in ("viewer", "operator", "engineer"):
            keys[role] = create_key(db, f"test {role}", Role[role])[1]
        keys["operator2"] = create_key(db, "second operator", Role.operator)[1]
        yield Rig(client, tmp, keys)


@pytest.fixture(scope="package")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    """One running service shared by the app tests, stopped after the last of them."""
    yield from make_rig(tmp_path_factory.mktemp("data"), viewer=True)


def poll(fn, deadline_s: float = 5.0, interval_s: float = 0.05):  # type: ignore[no-untyped-def]
    """Call ``fn`` until it returns a truthy value or the deadline passes; return the last value."""
    import time

    end = time.monotonic() + deadline_s
    value = fn()
    while not value and time.monotonic() < end:
        time.sleep(interval_s)
        value = fn()
    return value


@pytest.fixture
def board(tmp_path: Path) -> Iterator[Any]:
    """The motor controller emulator on a pseudo-terminal (a DC rig's serial board)."""
    from tracker.drivers.motor_emulator import MotorEmulator

    emu = MotorEmulator(pty_link=tmp_path / "ttyRIG")
    emu.start()
    yield emu
    emu.close()
