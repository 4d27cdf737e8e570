"""The friction-ID sweep on the service's own DC rig (a serial motor controller), not a twin.

The rig is lent to the job (:meth:`tracker.drivers.serial_motor.SerialMotorDriver.take_over`):
the control loop's own thread runs the sweep
(:func:`tracker.workbench.experiments.friction_id.friction_sweep`) one step per sample exchange,
at the loop's clock, the soft limits and faults as always, while this coroutine
(:meth:`app.jobs.JobRunner.start_local`) waits for its result; the console's plots show the
sweep as it runs. At the end (done, failed or cancelled) the command goes to 0 V and the rig
is handed back: the loop holds it where it stopped.

:func:`check_rig` says why the job cannot start (409 :class:`app.errors.Conflict`): the driver
is not a serial rig, tracking is on, a fault is latched, the rig is disabled, not connected, or
lent already.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any

from app.errors import Conflict
from app.lending import check_free
from app.modelio import plain
from tracker.errors import DriverFault

KIND = "friction-id"
TRAVEL_SHARE = 0.85  # of the driver's own limit lines, either side of zero
POLL_S = 0.1
STALL_S = 10.0  # no sample exchange for this long: the control loop stopped; the job fails


def check_rig(engine: Any, driver_url: str) -> Any:  # noqa: ANN401 - engine in, SerialMotorDriver out
    """The engine's serial rig, ready for the sweep; Conflict naming what is in the way."""
    from tracker.drivers.serial_motor import SerialMotorDriver

    rig = getattr(engine, "driver", None)
    if not isinstance(rig, SerialMotorDriver):
        raise Conflict(
            f"friction-ID on the live rig needs a serial motor controller (serial:///dev/ttyUSB0); "
            f"this service's driver is {driver_url!r}. Use source 'rig' (a twin built like it) or "
            "'practice'; on a PTZ camera run the speed-table identification (POST /api/v1/jobs/speed-id)",
            driver=driver_url,
        )
    check_free(engine, rig, "rig", "friction-ID sweep")
    return rig


def friction_live_job(
    rig: Any,  # noqa: ANN401 - a SerialMotorDriver
    axis: str,
    voltages: int = 10,
) -> Callable[[Callable[[float, str], None], Callable[[], bool]], Awaitable[dict[str, Any]]]:
    """The job for :meth:`app.jobs.JobRunner.start_local`: the friction lines, JSON-ready."""
    from tracker.workbench.experiments.friction_id import friction_sweep

    lo, hi = rig.limits(axis)
    travel_rad = TRAVEL_SHARE * min(-lo, hi)

    async def run(progress: Callable[[float, str], None], cancel: Callable[[], bool]) -> dict[str, Any]:
        loop = asyncio.get_running_loop()

        def report(fraction: float) -> None:  # from the control loop's thread: the store lives here
            loop.call_soon_threadsafe(progress, fraction, f"{axis}: {100 * fraction:.0f} % of the sweep")

        sweep = friction_sweep(axis, rig.sample_period_s, (rig.read_encoder(axis), rig.sample_time_s),
                               travel_rad=travel_rad, voltages_per_direction=voltages, progress=report,
                               cancel=cancel, limits_rad=(lo, hi))  # its moves never pass them
        progress(0.0, f"{axis}: sweeping the rig {rig.spec.url}")
        done = rig.take_over(f"the {KIND} job", axis, sweep)
        try:
            seen, since = rig.samples, loop.time()
            while not done.done():
                await asyncio.sleep(POLL_S)
                if rig.samples != seen:
                    seen, since = rig.samples, loop.time()
                elif loop.time() - since > STALL_S:
                    raise DriverFault(f"{rig.spec.url}: the control loop made no exchange for "
                                      f"{STALL_S:g} s during the sweep")
            res = done.result()
        finally:
            rig.hand_back()  # a no-op when the sweep ended by itself
        out: dict[str, Any] = plain(res.to_dict())
        out["driver"] = rig.spec.url
        return out

    return run
