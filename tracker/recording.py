"""Record an engine run into the measurement log format (one Measurement per axis: t, u, theta).

:class:`Recorder` keeps everything while recording is on; :class:`RecentLog` always keeps the
last few seconds (the engine checks a model offered to the controller against them).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tracker.errors import ConfigError, DataError
from tracker.workbench.measurements.data import MIN_SAMPLES, Measurement, write_log


class Recorder:
    """Collects per-sample (t, u, theta) chunks of each axis while recording is on."""

    def __init__(self, axes: tuple[str, ...], source: str = "engine") -> None:
        self._axes = axes
        self._source = source
        self._chunks: dict[str, list[NDArray[np.float64]]] = {a: [] for a in axes}

    def add(
        self, axis: str, t_s: NDArray[np.float64], u_v: NDArray[np.float64], theta_rad: NDArray[np.float64]
    ) -> None:
        """Append samples (each shape (n,))."""
        self._chunks[axis].append(np.column_stack([t_s, u_v, theta_rad]))

    def measurements(self) -> dict[str, Measurement]:
        """What was recorded, per axis."""
        out: dict[str, Measurement] = {}
        for axis, chunks in self._chunks.items():
            if not chunks:
                raise DataError(f"recording of {axis} is empty: the engine did not run while recording")
            a = np.vstack(chunks)
            out[axis] = Measurement(a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy(), f"{self._source}:{axis}")
        return out


class RecentLog:
    """A ring buffer of the last ``capacity`` samples of (t, u, theta) of each axis."""

    def __init__(self, axes: tuple[str, ...], capacity: int, source: str = "engine (recent)") -> None:
        if capacity < MIN_SAMPLES:
            raise ConfigError(f"RecentLog needs room for at least {MIN_SAMPLES} samples, got {capacity}")
        self._source = source
        self._data = {a: np.zeros((capacity, 3)) for a in axes}
        self._count = {a: 0 for a in axes}  # samples ever added; the newest is at (count - 1) % capacity

    def add(
        self, axis: str, t_s: NDArray[np.float64], u_v: NDArray[np.float64], theta_rad: NDArray[np.float64]
    ) -> None:
        """Append samples (each shape (n,)), dropping the oldest beyond the capacity."""
        buf = self._data[axis]
        cap = buf.shape[0]
        n = int(t_s.shape[0])
        chunk = np.column_stack([t_s, u_v, theta_rad])[-cap:]
        start = (self._count[axis] + n - chunk.shape[0]) % cap
        first = min(chunk.shape[0], cap - start)
        buf[start : start + first] = chunk[:first]
        buf[: chunk.shape[0] - first] = chunk[first:]
        self._count[axis] += n

    def measurement(self, axis: str) -> Measurement | None:
        """The samples held for ``axis``, oldest first (a copy); None while fewer than the
        workbench's minimum log length."""
        buf = self._data[axis]
        cap = buf.shape[0]
        count = self._count[axis]
        if count < MIN_SAMPLES:
            return None
        held = buf[:count] if count <= cap else np.roll(buf, -(count % cap), axis=0)
        return Measurement(held[:, 0].copy(), held[:, 1].copy(), held[:, 2].copy(), f"{self._source}:{axis}")


def write_measurements(measurements: dict[str, Measurement], path: str | Path) -> list[Path]:
    """Write one log per axis: ``path`` itself for a single axis, else ``<stem>_<axis><suffix>``."""
    p = Path(path)
    written: list[Path] = []
    for axis, m in measurements.items():
        target = p if len(measurements) == 1 else p.with_name(f"{p.stem}_{axis}{p.suffix or '.csv'}")
        write_log(target, m)
        written.append(target)
    return written
