"""The motor driver interface of the pan/tilt rig: enable, command volts, read encoders, faults.

A fault (over-travel, a non-finite command, a device error) *latches*: the driver disables
itself and refuses to enable again until :meth:`MotorDriver.clear_faults`.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from tracker.errors import DriverFault

AXES: tuple[str, ...] = ("pan", "tilt")


@runtime_checkable
class MotorDriver(Protocol):
    """One amplifier channel and one encoder per axis, sampled every ``sample_period_s``."""

    @property
    def axes(self) -> tuple[str, ...]:
        """Axis names, e.g. ("pan", "tilt")."""
        ...

    @property
    def sample_period_s(self) -> float:
        """The control sample period (s)."""
        ...

    @property
    def sample_time_s(self) -> float:
        """When the latest reading was taken (s), on the device's own clock where it has one: a
        host's sample may slip, the board's time stamp does not (velocities in the friction-ID
        come from these, not from the nominal period). The twin counts its samples."""
        ...

    @property
    def enabled(self) -> bool:
        """True while the amplifiers are enabled."""
        ...

    def enable(self) -> None:
        """Enable the amplifiers; raises DriverFault while a fault is latched."""
        ...

    def disable(self) -> None:
        """Disable the amplifiers (0 V); always allowed."""
        ...

    def command(self, axis: str, volts: float) -> None:
        """Set the amplifier command of ``axis`` (V) for the next sample."""
        ...

    def read_encoder(self, axis: str) -> float:
        """The encoder angle of ``axis`` at the load (rad)."""
        ...

    def tick(self) -> None:
        """Let one sample period pass (real hardware waits; the simulation integrates)."""
        ...

    def faults(self) -> tuple[str, ...]:
        """Latched faults, each a message naming the axis and cause."""
        ...

    def clear_faults(self) -> None:
        """Clear latched faults (the driver stays disabled until enabled again)."""
        ...


class FaultLatch:
    """The latched faults every driver keeps (the twin, the serial rig, the camera): a fault
    disables the driver and stays until :meth:`clear_faults`; :meth:`refuse_if_faulted` is the
    check ``enable`` makes. The driver defines ``disable`` and sets ``self._faults = []``."""

    _faults: list[str]

    def disable(self) -> None:
        raise NotImplementedError

    def faults(self) -> tuple[str, ...]:
        return tuple(self._faults)

    def clear_faults(self) -> None:
        self._faults.clear()

    def latch_fault(self, message: str) -> None:
        """Latch a fault (once) and disable."""
        if message not in self._faults:
            self._faults.append(message)
        self.disable()

    def refuse_if_faulted(self) -> None:
        """DriverFault naming the latched faults, if any (before enabling)."""
        if self._faults:
            raise DriverFault(f"cannot enable: fault latched ({'; '.join(self._faults)})")


@runtime_checkable
class ClosedLoopDriver(MotorDriver, Protocol):
    """A driver that can run the compiled controller itself for a chunk of samples (the twin)."""

    def run_closed_loop(
        self, axis: str, cp: NDArray[np.float64], cs: NDArray[np.float64], targets_rad: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Run ``targets_rad.shape[0]`` samples of the controller ``cp``/``cs`` on ``axis``.

        Returns the per-sample record, shape (n, N_REC) (see tracker.control.closed_loop).
        All axes must be advanced by the same number of samples before time moves on.
        """
        ...
