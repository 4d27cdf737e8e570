"""Record an engine run into the measurement log format (one Measurement per axis: t, u, theta)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tracker.errors import DataError
from tracker.workbench.data import Measurement, write_log


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


def write_measurements(measurements: dict[str, Measurement], path: str | Path) -> list[Path]:
    """Write one log per axis: ``path`` itself for a single axis, else ``<stem>_<axis><suffix>``."""
    p = Path(path)
    written: list[Path] = []
    for axis, m in measurements.items():
        target = p if len(measurements) == 1 else p.with_name(f"{p.stem}_{axis}{p.suffix or '.csv'}")
        write_log(target, m)
        written.append(target)
    return written
