"""Conversions between stored JSON and engine values: models, measurements, plot series (degrees)."""

from __future__ import annotations

import math
from typing import Any, TypeVar

import numpy as np

from app.db import Database
from app.errors import NotFound
from tracker.plant.model import AxisModel
from tracker.workbench.version_db import model_from_record, model_record

MAX_PLOT_POINTS = 1500
T = TypeVar("T")


def model_to_json(model: AxisModel, axis: str) -> dict[str, Any]:
    """A model as stored in a version (the format `tracker model --db` reads and writes)."""
    return model_record(model, axis)


def model_from_json(data: dict[str, Any]) -> AxisModel:
    """The stored model back (parameters as stored, not reset to defaults)."""
    return model_from_record(data)


def load_version(
    db: Database, measurement_id: int, version_id: int | None
) -> tuple[dict[str, Any], AxisModel]:
    """A version of the measurement's model (the latest when ``version_id`` is None)."""
    v = load_version_record(db, measurement_id, version_id)
    return v, model_from_json(v["model"])


def load_version_record(db: Database, measurement_id: int, version_id: int | None) -> dict[str, Any]:
    """The stored version record (model JSON not parsed); NotFound (404) when there is none."""
    if version_id is None:
        versions = db.list_versions(measurement_id)
        if not versions:
            raise NotFound(f"measurement {measurement_id} has no model versions")
        v = versions[-1]
    else:
        got = db.get_version(version_id)
        if got is None or got["measurement_id"] != measurement_id:
            raise NotFound(f"no version {version_id} of measurement {measurement_id}")
        v = got
    return v


def decimate_index(n: int, max_points: int = MAX_PLOT_POINTS) -> np.ndarray:
    """Indices that keep at most ``max_points`` evenly spread samples."""
    step = max(1, math.ceil(n / max_points))
    return np.arange(0, n, step)


def series_deg(t_s: np.ndarray, **arrays_rad: np.ndarray) -> dict[str, list[float]]:
    """Decimated plot series: ``t_s`` and each array converted to degrees (key ``<name>_deg``)."""
    idx = decimate_index(len(t_s))
    out = {"t_s": np.round(t_s[idx], 5).tolist()}
    for name, arr in arrays_rad.items():
        out[f"{name}_deg"] = np.round(np.degrees(np.asarray(arr)[idx]), 5).tolist()
    return out


def plain(value: T) -> T:
    """JSON-ready copy (numpy arrays/scalars to lists/floats, non-finite floats to None)."""
    out: Any = value
    if isinstance(value, dict):
        out = {str(k): plain(v) for k, v in value.items()}
    elif isinstance(value, list | tuple):
        out = [plain(v) for v in value]
    elif isinstance(value, np.ndarray):
        out = plain(value.tolist())
    elif isinstance(value, np.generic):
        out = plain(value.item())
    elif isinstance(value, float) and not math.isfinite(value):
        out = None
    return out  # type: ignore[no-any-return]
