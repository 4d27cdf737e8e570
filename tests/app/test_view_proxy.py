"""The 3D view through the console (real sockets: uvicorn on a free port, viser on loopback):
refused before any byte reaches viser without a key or view session; with one, viser's client
loads and its WebSocket messages cross the relay both ways; revoking the key closes the view."""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import msgspec
import pytest
import uvicorn
import viser
import zstandard
from viser import _messages
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus

from app.auth import Role, create_key
from app.main import create_app
from app.settings import load_settings

from .conftest import free_port

SUBPROTOCOL = f"viser-v{viser.__version__}"


@dataclass
class Served:
    base: str
    ws: str
    app: Any
    keys: dict[str, str]

    @property
    def viewer(self) -> Any:  # noqa: ANN401
        return self.app.state.svc.viewer


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    tmp: Path = tmp_path_factory.mktemp("view")
    settings = load_settings(None, data_dir=str(tmp), viewer_enabled=True, viewer_port=free_port(),
                             audio_enabled=False)
    app = create_app(settings)
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 60
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.started
    db = app.state.db
    keys = {"admin": (tmp / "admin.key").read_text().strip(),
            "viewer": create_key(db, "view test viewer", Role.viewer)[1],
            "doomed": create_key(db, "view test doomed", Role.viewer)[1]}
    try:
        yield Served(f"http://127.0.0.1:{port}", f"ws://127.0.0.1:{port}/api/v1/view", app, keys)
    finally:
        server.should_exit = True
        thread.join(timeout=30)


def test_viser_listens_on_loopback_only(served: Served) -> None:
    assert served.viewer.host == "127.0.0.1"
    state = httpx.get(f"{served.base}/api/v1/viewer", headers={"X-API-Key": served.keys["viewer"]}).json()
    assert state["url"] == "/api/v1/view/"
    assert state["direct_url"] == f"http://127.0.0.1:{served.viewer.port}/"


def test_the_client_page_needs_a_key_or_session(served: Served) -> None:
    r = httpx.get(f"{served.base}/api/v1/view/")
    assert r.status_code == 401 and r.json()["error"] == "Unauthorized", r.text
    r = httpx.get(f"{served.base}/api/v1/view/", cookies={"3dat_view": "made-up"})
    assert r.status_code == 401
    r = httpx.get(f"{served.base}/api/v1/view/", headers={"X-API-Key": served.keys["viewer"]})
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    assert "<title>Viser</title>" in r.text
    assert r.headers["cache-control"] == "no-store"
    assert httpx.get(f"{served.base}/api/v1/view/../main.py",
                     headers={"X-API-Key": served.keys["viewer"]}).status_code == 404


def test_a_view_session_is_an_httponly_cookie_for_the_view_only(served: Served) -> None:
    assert httpx.post(f"{served.base}/api/v1/view/session").status_code == 401
    r = httpx.post(f"{served.base}/api/v1/view/session", headers={"X-API-Key": served.keys["viewer"]})
    assert r.status_code == 200 and r.json()["url"] == "/api/v1/view/"
    cookie = r.headers["set-cookie"]
    for attribute in ("HttpOnly", "Path=/api/v1/view", "SameSite=strict"):
        assert attribute.lower() in cookie.lower(), cookie
    token = r.cookies["3dat_view"]
    page = httpx.get(f"{served.base}/api/v1/view/", cookies={"3dat_view": token})
    assert page.status_code == 200 and "<title>Viser</title>" in page.text
    # the cookie is good for the view, not for the API
    assert httpx.get(f"{served.base}/api/v1/status", cookies={"3dat_view": token}).status_code == 401


async def _refused(url: str, **kw: Any) -> int:  # noqa: ANN401
    try:
        async with connect(url, subprotocols=[SUBPROTOCOL], open_timeout=10, **kw):  # type: ignore[list-item]
            return 101
    except InvalidStatus as exc:
        return int(exc.response.status_code)


def test_the_websocket_is_refused_before_anything_reaches_viser(served: Served) -> None:
    before = len(served.viewer.server.get_clients())
    assert asyncio.run(_refused(served.ws)) == 401
    assert asyncio.run(_refused(served.ws, additional_headers={"Cookie": "3dat_view=made-up"})) == 401
    # a page of another site cannot ride a view session into the socket
    r = httpx.post(f"{served.base}/api/v1/view/session", headers={"X-API-Key": served.keys["viewer"]})
    evil = {"Cookie": f"3dat_view={r.cookies['3dat_view']}", "Origin": "https://evil.example"}
    assert asyncio.run(_refused(served.ws, additional_headers=evil)) == 403
    assert len(served.viewer.server.get_clients()) == before == 0


def _camera_message(position: tuple[float, float, float]) -> bytes:
    msg = _messages.ViewerCameraMessage(
        wxyz=(1.0, 0.0, 0.0, 0.0), position=position, fov=1.0, near=0.01, far=100.0,
        image_height=480, image_width=640, look_at=(0.0, 0.0, 0.0), up_direction=(0.0, 0.0, 1.0),
    )
    return msgspec.msgpack.encode(msg.as_serializable_dict())


async def _view_round_trip(served: Served, headers: dict[str, str]) -> tuple[set[str], list[Any]]:
    """Open the view through the relay, collect the scene's node names viser sends, send a
    camera pose and return what the server's client handle saw."""
    names: set[str] = set()
    async with connect(served.ws, subprotocols=[SUBPROTOCOL], additional_headers=headers,  # type: ignore[list-item]
                       max_size=None, open_timeout=10) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        deadline = time.monotonic() + 20
        while "/room/pan" not in names and time.monotonic() < deadline:
            raw = await asyncio.wait_for(ws.recv(), timeout=10)
            assert isinstance(raw, bytes)
            _collect_names(_decode_window(raw), names)
        await ws.send(_camera_message((1.5, 2.5, 3.5)))
        positions: list[Any] = []
        while time.monotonic() < deadline:
            clients = served.viewer.server.get_clients()
            positions = [tuple(round(float(x), 3) for x in c.camera.position) for c in clients.values()
                         if _has_camera(c)]
            if (1.5, 2.5, 3.5) in positions:
                break
            await asyncio.sleep(0.05)
        return names, positions


def _decode_window(raw: bytes) -> Any:  # noqa: ANN401
    """A window of viser's messages: two little-endian sizes, then zstd-compressed msgpack
    (viser/infra/_infra.py, ``_message_producer``)."""
    size = int.from_bytes(raw[:8], "little")
    compressed = int.from_bytes(raw[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(raw[16:16 + compressed], max_output_size=size)
    return msgspec.msgpack.decode(inner)


def _has_camera(client: Any) -> bool:  # noqa: ANN401
    try:
        client.camera.position  # noqa: B018 - raises until the first camera message
    except Exception:
        return False
    return True


def _collect_names(obj: Any, names: set[str]) -> None:  # noqa: ANN401
    if isinstance(obj, dict):
        name = obj.get("name")
        if isinstance(name, str):
            names.add(name)
        for value in obj.values():
            _collect_names(value, names)
    elif isinstance(obj, list):
        for value in obj:
            _collect_names(value, names)


def test_messages_cross_the_relay_both_ways_with_a_key(served: Served) -> None:
    names, positions = asyncio.run(_view_round_trip(served, {"X-API-Key": served.keys["viewer"]}))
    assert {"/room/pan", "/room/pan/tilt", "/room/target"} <= names  # the rig's scene, from viser
    assert (1.5, 2.5, 3.5) in positions  # our camera pose, at viser


def test_messages_cross_the_relay_with_the_console_s_session(served: Served) -> None:
    r = httpx.post(f"{served.base}/api/v1/view/session", headers={"X-API-Key": served.keys["viewer"]})
    headers = {"Cookie": f"3dat_view={r.cookies['3dat_view']}", "Origin": served.base}
    names, positions = asyncio.run(_view_round_trip(served, headers))
    assert "/room/pan" in names and (1.5, 2.5, 3.5) in positions


async def _revoked_while_viewing(served: Served) -> tuple[int, str]:
    r = httpx.post(f"{served.base}/api/v1/view/session", headers={"X-API-Key": served.keys["doomed"]})
    headers = {"Cookie": f"3dat_view={r.cookies['3dat_view']}"}
    async with connect(served.ws, subprotocols=[SUBPROTOCOL], additional_headers=headers,  # type: ignore[list-item]
                       max_size=None, open_timeout=10) as ws:
        await asyncio.wait_for(ws.recv(), timeout=10)
        doomed = next(k for k in served.app.state.db.list_keys() if k.name == "view test doomed")
        async with httpx.AsyncClient() as client:
            gone = await client.delete(f"{served.base}/api/v1/keys/{doomed.id}",
                                       headers={"X-API-Key": served.keys["admin"]})
            assert gone.status_code == 204
        try:
            while True:
                await asyncio.wait_for(ws.recv(), timeout=5)
        except ConnectionClosed as closed:
            assert closed.rcvd is not None
            return closed.rcvd.code, closed.rcvd.reason
    return 0, ""


def test_revoking_the_key_closes_its_view_and_its_session(served: Served) -> None:
    code, reason = asyncio.run(_revoked_while_viewing(served))
    assert (code, reason) == (4401, "API key revoked")
    assert asyncio.run(_refused(served.ws, additional_headers={"X-API-Key": served.keys["doomed"]})) == 401
