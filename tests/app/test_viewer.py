"""The viser 3D view: frames follow telemetry, and the share-URL tunnel cannot be opened."""

from __future__ import annotations

import asyncio
import math
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.viewer import RigViewer, angle_about_y, angle_about_z, load_mics, quat_direction, quat_y, quat_z

from .conftest import free_port


@pytest.fixture(scope="module")
def viewer() -> Iterator[RigViewer]:
    v = RigViewer("127.0.0.1", free_port(), load_mics(None))
    yield v
    v.server.stop()


def rotate(q: tuple[float, float, float, float], v: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    u = np.array([x, y, z])
    return v + 2 * np.cross(u, np.cross(u, v) + w * v)


@settings(max_examples=50, deadline=None)
@given(az=st.floats(-math.pi, math.pi), el=st.floats(-1.5, 1.5))
def test_direction_quaternion_points_x_at_azimuth_and_elevation(az: float, el: float) -> None:
    expected = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    np.testing.assert_allclose(rotate(quat_direction(az, el), np.array([1.0, 0, 0])), expected, atol=1e-12)


@given(a=st.floats(-3.0, 3.0))
def test_axis_angles_read_back(a: float) -> None:
    assert angle_about_z(quat_z(a)) == pytest.approx(a, abs=1e-12)
    assert angle_about_y(quat_y(a)) == pytest.approx(a, abs=1e-12)


def test_scene_follows_a_frame(viewer: RigViewer) -> None:
    viewer.show(
        {
            "pan_deg": -33.0,
            "tilt_deg": 12.5,
            "pan_target_deg": -30.0,
            "tilt_target_deg": 10.0,
            "estimate_azimuth_deg": None,
            "estimate_elevation_deg": None,
        }
    )
    s = viewer.scene_state()
    assert (s["pan_deg"], s["tilt_deg"]) == (pytest.approx(-33.0), pytest.approx(12.5))
    assert s["estimate_visible"] is False
    viewer.show(
        {"pan_deg": 0.0, "tilt_deg": 0.0, "estimate_azimuth_deg": 40.0, "estimate_elevation_deg": None}
    )
    assert viewer.scene_state()["estimate_visible"] is True


def test_share_url_is_disabled_for_real(viewer: RigViewer) -> None:
    from viser import _messages

    assert viewer.share_enabled is False
    assert viewer.scene_state()["share_url_enabled"] is False
    # a client asking for a share URL reaches no handler, so no tunnel is ever started
    ws = viewer.server._websock_server
    assert _messages.ShareUrlRequest not in ws._incoming_handlers
    asyncio.run(ws._handle_incoming_message(0, _messages.ShareUrlRequest()))  # type: ignore[arg-type]
    assert viewer.server._share_tunnel is None
    # and the server-side call refuses too
    assert viewer.server.request_share_url() is None
    assert viewer.server._share_tunnel is None


def test_binds_loopback_by_default() -> None:
    from app.settings import Settings

    assert Settings().viewer_host == "127.0.0.1"
    assert Settings().host == "127.0.0.1"


def test_the_trail_keeps_the_last_estimates(viewer: RigViewer) -> None:
    for k in range(100):
        viewer.show(
            {
                "t_s": 100.0 + 0.1 * k,
                "pan_deg": 0.0,
                "tilt_deg": 0.0,
                "estimate_azimuth_deg": 30.0 if k % 2 else -20.0,
                "estimate_elevation_deg": None,
            }
        )
    s = viewer.scene_state()
    assert s["trail_points"] == 40
    pts = np.asarray(viewer.trail.points, dtype=float)
    az = np.degrees(np.arctan2(pts[:, 1], pts[:, 0]))
    assert set(np.round(az).astype(int)) == {30, -20}
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), 2.5, rtol=2e-3)  # viser stores float16


def test_a_head_mounted_array_is_drawn_on_the_head() -> None:
    """The seed's pairs ride on the pan/tilt head: the view draws them under the tilt frame
    (they turn with the camera); the shipped square stays on the base."""
    from pathlib import Path

    from app.viewer import array_is_head_mounted

    arrays = Path(__file__).resolve().parents[2] / "examples" / "arrays"
    assert array_is_head_mounted(arrays / "seed_pairs.json")
    assert not array_is_head_mounted(arrays / "square4_65mm.json")
    assert not array_is_head_mounted(None)
    v = RigViewer("127.0.0.1", free_port(), load_mics(arrays / "seed_pairs.json"), head_mounted=True)
    try:
        assert v.mics.name.startswith("/room/pan/tilt/")
    finally:
        v.server.stop()


def test_each_talker_followed_is_a_dot_the_speaking_one_green(viewer: RigViewer) -> None:
    viewer.show_talkers([
        {"talker_id": 0, "azimuth_deg": 35.0, "elevation_deg": None, "speaking": False},
        {"talker_id": 1, "azimuth_deg": -40.0, "elevation_deg": 10.0, "speaking": True},
    ])
    pts = np.asarray(viewer.talker_dots.points, dtype=float)
    colors = np.asarray(viewer.talker_dots.colors)
    assert viewer.talker_dots.visible and viewer.scene_state()["talkers_shown"] == 2
    assert np.degrees(np.arctan2(pts[:, 1], pts[:, 0])) == pytest.approx([35.0, -40.0], abs=0.1)  # float16
    assert np.degrees(np.arcsin(pts[1, 2] / np.linalg.norm(pts[1]))) == pytest.approx(10.0, abs=0.1)
    assert tuple(colors[1]) == (20, 170, 70) and tuple(colors[0]) != tuple(colors[1])
    viewer.show_talkers([])
    assert not viewer.talker_dots.visible and viewer.scene_state()["talkers_shown"] == 0
