"""The viser 3D view of the rig: mount and camera frustum turning live, microphone array, talker
estimate and current target. viser runs on its own port, bound to loopback by default; browsers
reach it through the console (``/api/v1/view/``, same origin, same keys: app/view_proxy.py).

viser has no authentication, so the share-URL feature (a public tunnel through an outside relay
that any connected client can request with one message) is disabled for real: the server's
handlers for the share request messages are removed and ``request_share_url`` refuses, on top of
hiding the button. Frames (z up, metres): room → pan (rotates about z by the pan angle) → tilt
(rotates about the head's y so that +x tilts up by the tilt angle); the camera looks along the
tilt frame's +x. Azimuth is measured from +x toward +y, elevation up from the horizontal.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from app.view_proxy import VIEW_PATH

log = logging.getLogger("app.viewer")

MOUNT_HEIGHT_M = 1.2
TRAIL_POINTS = 40
TRAIL_PERIOD_S = 0.1
ARRAY_HEIGHT_M = 1.0
RAY_LENGTH_M = 2.5
LOOPBACK_HOSTS = {"127.0.0.1", "::1", "localhost"}
# Rotates viser's camera-frustum frame (looks along +z, +y down) to look along +x with +z up.
_R_HEAD_FRUSTUM = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def quat_z(angle_rad: float) -> tuple[float, float, float, float]:
    """Quaternion (wxyz) of a rotation by ``angle_rad`` about +z."""
    return (math.cos(angle_rad / 2), 0.0, 0.0, math.sin(angle_rad / 2))


def quat_y(angle_rad: float) -> tuple[float, float, float, float]:
    """Quaternion (wxyz) of a rotation by ``angle_rad`` about +y."""
    return (math.cos(angle_rad / 2), 0.0, math.sin(angle_rad / 2), 0.0)


def quat_direction(azimuth_rad: float, elevation_rad: float) -> tuple[float, float, float, float]:
    """Rotation taking +x to the direction (azimuth, elevation): Rz(az)·Ry(−el)."""
    a, e = azimuth_rad / 2, -elevation_rad / 2
    ca, sa, ce, se = math.cos(a), math.sin(a), math.cos(e), math.sin(e)
    return (ca * ce, -sa * se, ca * se, sa * ce)


def angle_about_z(wxyz: Any) -> float:
    """The angle of a pure z rotation given as a quaternion (rad)."""
    w, _, _, z = (float(v) for v in wxyz)
    return 2.0 * math.atan2(z, w)


def angle_about_y(wxyz: Any) -> float:
    """The angle of a pure y rotation given as a quaternion (rad)."""
    w, _, y, _ = (float(v) for v in wxyz)
    return 2.0 * math.atan2(y, w)


def array_is_head_mounted(path: Path | None) -> bool:
    """True when the array JSON says ``"mount": "head"`` (the shipped default is on the base)."""
    from tracker.audio.array import load_array

    return path is not None and load_array(path).head_mounted


def load_mics(path: Path | None) -> np.ndarray:
    """Microphone positions (n_mics, 3) in metres from an array JSON (validated by
    ``tracker.audio.array.load_array``); the shipped 4-mic square by default (as the meeting)."""
    from tracker.audio.array import load_array
    from tracker.resources import project_dir

    default = project_dir("examples") / "arrays" / "square4_65mm.json"
    return np.asarray(load_array(path or default).positions_m, dtype=float)


def _refuse_share_url(*_: Any, **__: Any) -> None:
    log.warning("viser share URL requested and refused: the share feature is disabled in this service")
    return None


class RigViewer:
    """The viser server and the scene handles it updates from telemetry."""

    def __init__(self, host: str, port: int, mics_m: np.ndarray, head_mounted: bool = False) -> None:
        import viser
        from viser import _messages

        self.server = viser.ViserServer(host=host, port=port, label="3DAT rig", verbose=False)
        # Disable the share tunnel for real: no handler, and the method refuses if called anyway.
        ws = self.server._websock_server
        for msg_cls in (_messages.ShareUrlRequest, _messages.ShareUrlDisconnect):
            with contextlib.suppress(AssertionError, KeyError):
                ws.unregister_handler(msg_cls)
        self.server.request_share_url = _refuse_share_url  # type: ignore[method-assign]
        self.server.gui.configure_theme(show_share_button=False, show_logo=False, dark_mode=False)
        with contextlib.suppress(AttributeError):
            self.server.initial_camera.position = (-1.6, -2.4, 2.3)
            self.server.initial_camera.look_at = (0.6, 0.0, 1.0)
        self.host = host
        self.port = self.server.get_port()
        if host not in LOOPBACK_HOSTS:
            log.warning("viser listens on %s:%d with no authentication; browsers get the view through "
                        "the console (%s/): set viewer_host = \"127.0.0.1\"", host, self.port, VIEW_PATH)
        self.head_mounted = bool(head_mounted)
        self._build_scene(mics_m)
        self._task: asyncio.Task[None] | None = None
        self.pan_rad = 0.0
        self.tilt_rad = 0.0

    @property
    def share_enabled(self) -> bool:
        """True if any client message could open a share tunnel (must stay False)."""
        from viser import _messages

        handlers = self.server._websock_server._incoming_handlers
        return bool(handlers.get(_messages.ShareUrlRequest))

    def _build_scene(self, mics_m: np.ndarray) -> None:
        sc = self.server.scene
        sc.set_up_direction("+z")
        sc.add_grid("/room/floor", width=6.0, height=5.0, cell_size=0.5, position=(1.5, 0.0, 0.0))
        sc.add_cylinder(
            "/room/mast",
            radius=0.03,
            height=MOUNT_HEIGHT_M,
            color=(90, 90, 100),
            position=(0.0, 0.0, MOUNT_HEIGHT_M / 2),
        )
        self.pan_frame = sc.add_frame(
            "/room/pan", axes_length=0.15, axes_radius=0.006, position=(0.0, 0.0, MOUNT_HEIGHT_M)
        )
        sc.add_box("/room/pan/yoke", dimensions=(0.08, 0.2, 0.04), color=(60, 110, 170))
        self.tilt_frame = sc.add_frame(
            "/room/pan/tilt", axes_length=0.1, axes_radius=0.005, position=(0.0, 0.0, 0.06)
        )
        sc.add_box("/room/pan/tilt/camera", dimensions=(0.16, 0.08, 0.08), color=(40, 40, 48))
        from viser import transforms as tf

        self.frustum = sc.add_camera_frustum(
            "/room/pan/tilt/frustum",
            fov=math.radians(60),
            aspect=16 / 9,
            scale=0.35,
            color=(230, 120, 20),
            wxyz=tf.SO3.from_matrix(_R_HEAD_FRUSTUM).wxyz,
            position=(0.08, 0.0, 0.0),
        )
        self.array_frame = sc.add_frame("/room/array", show_axes=False, position=(0.0, 0.0, ARRAY_HEIGHT_M))
        # A head-mounted array (as in the seed) turns with the camera: draw it on the tilt frame.
        self.mics = sc.add_point_cloud(
            "/room/pan/tilt/mics" if self.head_mounted else "/room/array/mics",
            points=mics_m.astype(np.float32) * 3.0,
            colors=(20, 140, 60),
            point_size=0.03,
            point_shape="circle",
        )
        ray = np.array([[[0.0, 0.0, 0.0], [RAY_LENGTH_M, 0.0, 0.0]]], dtype=np.float32)
        self.estimate_frame = sc.add_frame("/room/array/estimate", show_axes=False, visible=False)
        sc.add_line_segments("/room/array/estimate/ray", points=ray, colors=(20, 160, 70), thickness=0.012)
        sc.add_icosphere(
            "/room/array/estimate/talker", radius=0.12, color=(20, 160, 70), position=(RAY_LENGTH_M, 0.0, 0.0)
        )
        # The last few seconds of estimates: where the localizer heard talkers (a fading trail).
        self.trail = sc.add_point_cloud(
            "/room/array/trail",
            points=np.zeros((1, 3), dtype=np.float32),
            colors=(20, 160, 70),
            point_size=0.06,
            point_shape="circle",
            visible=False,
        )
        self._trail: deque[tuple[float, float, float]] = deque(maxlen=TRAIL_POINTS)
        self._trail_t = -math.inf
        self.target_frame = sc.add_frame("/room/target", show_axes=False, position=(0.0, 0.0, MOUNT_HEIGHT_M))
        sc.add_line_segments("/room/target/ray", points=ray, colors=(200, 40, 40), thickness=0.006)
        sc.add_icosphere(
            "/room/target/tip", radius=0.05, color=(200, 40, 40), position=(RAY_LENGTH_M, 0.0, 0.0)
        )
        # The talkers the tracker has followed (one dot each; the one speaking larger and green).
        self.talker_dots = sc.add_point_cloud(
            "/room/array/talkers", points=np.zeros((1, 3), dtype=np.float32), colors=(110, 120, 135),
            point_size=0.16, point_shape="circle", visible=False)
        self.talkers_shown = 0
        self.talkers: Any = None  # a callable giving the status' talkers (degrees), set by the service
        self.server.gui.add_markdown(
            "**3DAT rig** — orange: camera frustum · red: target · green: talker estimate "
            "(fading dots: the last 4 s) · grey dots: talkers followed (green: speaking) · "
            "dark green: microphones"
        )

    def show(self, frame: dict[str, Any]) -> None:
        """Move the scene to a telemetry frame (degrees, as sent on the WebSocket)."""
        pan = math.radians(frame.get("pan_deg") or 0.0)
        tilt = math.radians(frame.get("tilt_deg") or 0.0)
        self.pan_frame.wxyz = quat_z(pan)
        self.tilt_frame.wxyz = quat_y(-tilt)
        self.pan_rad, self.tilt_rad = pan, tilt
        pt, tt = frame.get("pan_target_deg"), frame.get("tilt_target_deg")
        if pt is not None and tt is not None:
            self.target_frame.wxyz = quat_direction(math.radians(pt), math.radians(tt))
        az, el = frame.get("estimate_azimuth_deg"), frame.get("estimate_elevation_deg")
        if az is None:
            self.estimate_frame.visible = False
        else:
            self.estimate_frame.wxyz = quat_direction(math.radians(az), math.radians(el or 0.0))
            self.estimate_frame.visible = True
        self._update_trail(frame.get("t_s"), az, el)

    def _update_trail(self, t_s: float | None, az_deg: float | None, el_deg: float | None) -> None:
        """Add an estimate to the trail every TRAIL_PERIOD_S of engine time; show the trail."""
        if t_s is None or az_deg is None or t_s - self._trail_t < TRAIL_PERIOD_S:
            if t_s is not None and t_s < self._trail_t:  # the engine clock restarted
                self._trail.clear()
                self._trail_t = -math.inf
            return
        self._trail_t = t_s
        self._trail.append((t_s, math.radians(az_deg), math.radians(el_deg or 0.0)))
        pts = (
            np.array(
                [
                    [math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)]
                    for _, a, e in self._trail
                ]
            )
            * RAY_LENGTH_M
        )
        age = (t_s - np.array([t for t, _, _ in self._trail])) / (TRAIL_POINTS * TRAIL_PERIOD_S)
        fade = np.clip(age, 0.0, 1.0)[:, None]
        colors = ((1 - fade) * np.array([20, 160, 70]) + fade * np.array([220, 230, 225])).astype(np.uint8)
        self.trail.points = pts.astype(np.float32)
        self.trail.colors = colors
        self.trail.visible = True

    def show_talkers(self, talkers: list[dict[str, Any]]) -> None:
        """One dot per talker followed (``azimuth_deg``, ``elevation_deg``, ``speaking``)."""
        self.talkers_shown = len(talkers)
        if not talkers:
            self.talker_dots.visible = False
            return
        az = np.radians([t["azimuth_deg"] for t in talkers])
        el = np.radians([t.get("elevation_deg") or 0.0 for t in talkers])
        pts = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)],
                       axis=1) * (RAY_LENGTH_M + 0.3)
        colors = np.array([(20, 170, 70) if t["speaking"] else (110, 120, 135) for t in talkers],
                          dtype=np.uint8)
        self.talker_dots.points = pts.astype(np.float32)
        self.talker_dots.colors = colors
        self.talker_dots.visible = True

    def scene_state(self) -> dict[str, Any]:
        """What the 3D scene shows now, read back from the viser handles (degrees)."""
        return {
            "url": VIEW_PATH + "/",  # through the console, with its keys (app/view_proxy.py)
            "direct_url": f"http://{self.host}:{self.port}/",  # viser itself: no authentication
            "port": self.port,
            "pan_deg": round(math.degrees(angle_about_z(self.pan_frame.wxyz)), 3),
            "tilt_deg": round(-math.degrees(angle_about_y(self.tilt_frame.wxyz)), 3),
            "estimate_visible": bool(self.estimate_frame.visible),
            "trail_points": len(self._trail),
            "talkers_shown": self.talkers_shown,
            "clients": len(self.server.get_clients()),
            "share_url_enabled": self.share_enabled,
        }

    def start(self, hub: Any, rate_hz: float) -> None:
        """Follow the telemetry hub's latest frame at ``rate_hz`` until :meth:`stop`."""
        self._task = asyncio.create_task(self._follow(hub, 1.0 / rate_hz), name="viser-view")

    async def _follow(self, hub: Any, period_s: float) -> None:
        last = None
        next_talkers = 0.0
        while True:
            now = asyncio.get_running_loop().time()
            if self.talkers is not None and now >= next_talkers:  # twice a second is plenty
                next_talkers = now + 0.5
                try:
                    self.show_talkers(self.talkers())
                except Exception:
                    log.exception("drawing the talkers in the 3D view failed")
            frame = hub.latest_frame
            if frame is not None and frame is not last:
                try:
                    self.show(frame)
                except Exception:
                    log.exception("updating the 3D view failed")
                last = frame
            await asyncio.sleep(period_s)

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        await asyncio.to_thread(self.server.stop)
