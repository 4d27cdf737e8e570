"""The camera driver interface: a PTZ head with its own position loop, steered by targets.

A :class:`MotorDriver` takes volts every millisecond and the engine closes the loop; a PTZ
camera closes its own loop and takes a speed or position command a few dozen times a second.
So the engine hands a :class:`CameraDriver` *targets* (where to point, rad) once per chunk
and reads back where the camera says it is; the driver turns them into the camera's commands
at its own ``command_period_s`` (speed drives shaped by the camera's speed table and its
acceleration, or absolute positions), and enforces the soft limits itself.

Faults latch as with a motor driver (the driver disables itself; :meth:`clear_faults` then
:meth:`enable`). A lost connection is such a fault: the driver reconnects by itself, but it
does not move the camera again until it is enabled and given a target.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class CameraDriver(Protocol):
    """A position/speed-commanded pan/tilt head (see the module docstring)."""

    @property
    def axes(self) -> tuple[str, ...]:
        """Axis names, ("pan", "tilt")."""
        ...

    @property
    def sample_period_s(self) -> float:
        """The engine's bookkeeping period (s); the camera itself is commanded every
        ``command_period_s``."""
        ...

    @property
    def command_period_s(self) -> float:
        """How often the driver commands the camera (s)."""
        ...

    @property
    def ready(self) -> bool:
        """True once connected and a position has been read since the (re)connection."""
        ...

    @property
    def enabled(self) -> bool:
        """True while the driver may move the camera."""
        ...

    def enable(self) -> None:
        """Allow motion from the next target on; DriverFault while a fault is latched or
        before the camera is ready."""
        ...

    def disable(self) -> None:
        """Stop the camera and forget the targets; always allowed."""
        ...

    def set_target(self, axis: str, angle_rad: float) -> None:
        """Where ``axis`` should point (rad, clamped to the soft limits); ignored while disabled."""
        ...

    def read_encoder(self, axis: str) -> float:
        """Where the camera last said ``axis`` points (rad), advanced by the commanded speed
        since then."""
        ...

    def faults(self) -> tuple[str, ...]:
        """Latched faults, each a message naming the cause."""
        ...

    def clear_faults(self) -> None:
        """Clear latched faults (the driver stays disabled until enabled again)."""
        ...

    def start(self) -> None:
        """Start talking to the camera (connects and reconnects in the background); needs a
        running event loop."""
        ...

    async def close(self) -> None:
        """Stop the camera and close the connection."""
        ...

    def describe(self) -> dict[str, Any]:
        """What the status shows: kind, address, profile, link state, rates, round trips."""
        ...
