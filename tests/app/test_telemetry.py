"""WS /telemetry: authenticated, ≥ 50 frames per second of wall time, many viewers at once."""

from __future__ import annotations

import json
import time

import pytest
from starlette.websockets import WebSocketDisconnect

from app.errors import Conflict, Forbidden, NotFound, Unauthorized, status_for
from app.telemetry import TelemetryHub
from tracker.errors import ConfigError, DataError, DriverFault, JobCancelled

from .conftest import Rig

FRAME_KEYS = {
    "t_s",
    "pan_deg",
    "tilt_deg",
    "pan_target_deg",
    "tilt_target_deg",
    "pan_u_v",
    "tilt_u_v",
    "mode",
    "tracking",
    "source",
    "estimate_azimuth_deg",
    "estimate_elevation_deg",
}


def test_two_viewers_each_get_at_least_50_frames_per_second(rig: Rig) -> None:
    with (
        rig.client.websocket_connect("/api/v1/telemetry") as a,
        rig.client.websocket_connect("/api/v1/telemetry") as b,
    ):
        a.send_text(json.dumps({"key": rig.keys["viewer"]}))
        b.send_text(json.dumps({"key": rig.keys["operator"]}))
        assert a.receive_json()["type"] == "hello" and b.receive_json()["type"] == "hello"
        a.receive_json()  # the first frame may have waited in the queue
        t0 = time.monotonic()
        frames = [a.receive_json() for _ in range(60)]
        wall_s = time.monotonic() - t0
        other = [b.receive_json() for _ in range(10)]
    rate_hz = len(frames) / wall_s
    assert rate_hz >= 50.0, f"{rate_hz:.1f} frames/s"
    assert FRAME_KEYS <= set(frames[0])
    dts = [f1["t_s"] - f0["t_s"] for f0, f1 in zip(frames, frames[1:], strict=False)]
    assert max(dts) <= 0.02 + 1e-6, "frames are more than 20 ms of engine time apart"
    assert all(f["type"] == "frame" for f in other)


def test_unknown_key_is_refused(rig: Rig) -> None:
    with rig.client.websocket_connect("/api/v1/telemetry") as ws:
        ws.send_text(json.dumps({"key": "3dat_wrong"}))
        with pytest.raises(WebSocketDisconnect) as exc:
            ws.receive_json()
    assert exc.value.code == 4401


def test_header_key_also_works(rig: Rig) -> None:
    with rig.client.websocket_connect("/api/v1/telemetry", headers=rig.h("viewer")) as ws:
        hello = ws.receive_json()
        assert hello["role"] == "viewer"
        assert ws.receive_json()["type"] == "frame"


class _Snap:
    def __init__(self, t_s: float) -> None:
        self.t_s, self.pan_rad, self.tilt_rad = t_s, 0.1, -0.05
        self.pan_target_rad = self.tilt_target_rad = 0.0
        self.pan_u_v = self.tilt_u_v = 0.0
        self.mode, self.tracking, self.source = "hold", False, None
        self.estimate_azimuth_rad = self.estimate_elevation_rad = None


def test_hub_decimates_to_its_rate_and_drops_oldest_for_slow_clients() -> None:
    hub = TelemetryHub(rate_hz=50.0)
    sub = hub.subscribe(maxsize=10)
    for k in range(1000):  # 1 s of engine time at 1 kHz
        hub.publish(_Snap(k * 1e-3))
    assert hub.frames_sent == 50
    assert sub.queue.qsize() == 10 and sub.dropped == 40
    assert sub.queue.get_nowait()["t_s"] == pytest.approx(0.8)
    assert hub.latest_frame["pan_deg"] == pytest.approx(5.7296, abs=1e-3)  # type: ignore[index]
    sub.close()
    assert hub.clients == 0


@pytest.mark.parametrize(
    ("exc", "status"),
    [
        (ConfigError("x"), 422),
        (DataError("x"), 400),
        (DriverFault("x"), 503),
        (JobCancelled("x"), 409),
        (Unauthorized("x"), 401),
        (Forbidden("x"), 403),
        (NotFound("x"), 404),
        (Conflict("x"), 409),
        (RuntimeError("x"), 500),
    ],
    ids=["config", "data", "driver", "cancelled", "401", "403", "404", "409", "unknown"],
)
def test_one_place_maps_engine_errors_to_http(exc: Exception, status: int) -> None:
    assert status_for(exc) == status
