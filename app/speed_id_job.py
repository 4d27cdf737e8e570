"""The speed-table identification job on the service's PTZ camera (the camera's friction-ID).

It runs on the service's event loop, where the camera's link lives
(:meth:`app.jobs.JobRunner.start_local`): the camera is lent to the job
(:meth:`tracker.drivers.visca.ViscaCamera.take_over`), so neither the engine's hold target nor
a jog steers it meanwhile, and :func:`tracker.workbench.camera.speed_id.identify_speed_table`
drives it step by step through :class:`~tracker.workbench.camera.speed_id.ViscaRig`. At the end
(done, failed or cancelled) the head is stopped and handed back: it returns to where the engine
held it.

:func:`check_camera` says why the job cannot start (409 :class:`app.errors.Conflict`): the driver
is not a camera, tracking is on, the camera is disabled, faulted, not connected, or lent already.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Awaitable, Callable
from typing import Any

from app.errors import Conflict
from app.lending import check_free
from app.modelio import plain
from tracker.errors import ConfigError, DriverFault

KIND = "speed-id"


def check_camera(engine: Any, driver_url: str) -> Any:  # noqa: ANN401 - engine in, ViscaCamera out
    """The engine's camera, ready for the identification; Conflict naming what is in the way."""
    from tracker.drivers.visca import ViscaCamera

    cam = getattr(engine, "driver", None)
    if not isinstance(cam, ViscaCamera):
        raise Conflict(
            f"speed-table identification needs a PTZ camera driver (visca+udp://HOST:PORT or "
            f"visca+tcp://...); this service's driver is {driver_url!r}. On a motor rig run friction-ID "
            "(POST /api/v1/jobs/friction-id); a profile's twin: `tracker camera speed-id`",
            driver=driver_url,
        )
    check_free(engine, cam, "camera", "speed-table identification")
    return cam


def speed_id_job(
    cam: Any,  # noqa: ANN401 - a ViscaCamera
    axis: str,
    steps: tuple[int, ...] | None,
    count: int,
) -> Callable[[Callable[[float, str], None], Callable[[], bool]], Awaitable[dict[str, Any]]]:
    """The job for :meth:`app.jobs.JobRunner.start_local`: JSON-ready result (the measured table
    against the profile's, rad/s and °/s)."""
    from tracker.drivers import visca_protocol as vp
    from tracker.workbench.camera.speed_id import ViscaRig, identify_speed_table

    n = len(cam.profile.speeds_rad_s[axis])
    bad = [s for s in steps or () if not 1 <= s <= n]
    if bad:
        raise ConfigError(f"steps {bad} are outside the {cam.profile.name} profile's {axis} table 1..{n}")

    async def run(progress: Callable[[float, str], None], cancel: Callable[[], bool]) -> dict[str, Any]:
        cam.take_over(f"the {KIND} job")
        try:
            progress(0.0, f"{axis}: driving the camera {cam.spec.url}")
            res = await identify_speed_table(
                ViscaRig(cam), axis, steps=steps, count=count, cancel=cancel,
                progress=lambda f: progress(f, f"{axis}: {100 * f:.0f} % of the steps measured"),
            )
        except DriverFault as exc:  # the link lost or the camera disabled mid-way
            raise DriverFault(f"speed-table identification stopped: {exc}") from None
        finally:
            with contextlib.suppress(DriverFault):
                await cam.command(vp.pan_tilt_stop())
            cam.hand_back()
        out: dict[str, Any] = plain(res.to_dict())
        out["driver"] = cam.spec.url
        out["table_deg_s"] = [
            {"step": r.step, "direction": r.direction, "measured_deg_s": math.degrees(r.rate_rad_s),
             "profile_deg_s": math.degrees(r.profile_rad_s), "deviation_percent": r.deviation_percent}
            for r in res.runs
        ]
        return out

    return run
