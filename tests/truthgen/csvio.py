"""CSV and JSON writing of a log (columns t,u,theta; full float precision) and its truth."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from tests.truthgen.run import Log


def log_csv(log: Log) -> str:
    """The log as CSV text: header ``t,u,theta`` then one row per tick (``%.17g``: round-trips)."""
    out = io.StringIO()
    out.write("t,u,theta\n")
    np.savetxt(out, np.column_stack([log.t, log.u, log.theta]), delimiter=",", fmt="%.17g")
    return out.getvalue()


def read_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t, u, theta)`` from a CSV written by :func:`log_csv`."""
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return data[:, 0], data[:, 1], data[:, 2]


def write_case(folder: str | Path, log: Log, truth: dict[str, Any]) -> Path:
    """Write ``<folder>/<split>/<id>.csv`` and ``<id>.json``; returns the CSV path."""
    d: Path = Path(folder) / str(truth["split"])
    d.mkdir(parents=True, exist_ok=True)
    csv: Path = d / f"{truth['id']}.csv"
    tmp = csv.with_name(csv.name + ".part")
    tmp.write_text(log_csv(log), encoding="utf-8")
    tmp.replace(csv)
    (d / f"{truth['id']}.json").write_text(
        json.dumps(truth, indent=1, sort_keys=False) + "\n", encoding="utf-8"
    )
    return csv
