"""The workbench's heavy work on a PTZ camera log (CSV ``t,speed_cmd,theta``), as pure functions
of plain values run in the worker processes of app/work.py (like app/heavy.py for DC logs).

A camera log is checked against the camera model of tracker/workbench/camera/ (latency, speed
table, acceleration, backlash, quantization), as ``tracker model compare|fit|diagnose`` does on
one. Its first version is the base camera model (linear speed table, no latency) with its speed
per step fitted; adding an effect refits every free parameter into a new version, as for a DC
log. A model travels as the JSON of ``CameraModel.to_dict`` (``"kind": "camera"``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from app.modelio import decimate_index, plain, series_deg
from tracker.errors import ConfigError
from tracker.workbench.camera.log import CameraLog, is_camera_log, parse_camera_log
from tracker.workbench.camera.model import CameraModel

KIND = "camera"


def is_camera(text: str) -> bool:
    """True when the stored CSV is a camera log (its header has ``speed_cmd``)."""
    return is_camera_log(text)


def _base(log: CameraLog) -> CameraModel:
    return CameraModel.base(log.max_step)


def is_camera_model(model_json: dict[str, Any]) -> bool:
    """True for a stored camera model (``CameraModel.to_dict``), False for a DC axis model."""
    return model_json.get("kind") == KIND


def model_from_json(model_json: dict[str, Any], log: CameraLog) -> CameraModel:
    """The stored camera model back (ConfigError naming a bad effect or parameter)."""
    if not is_camera_model(model_json):
        raise ConfigError("this version holds a DC axis model, not a camera model")
    effects = tuple(str(e) for e in model_json.get("effects") or ())
    n_steps = int(model_json.get("n_steps") or log.max_step)
    params = {str(k): float(v) for k, v in (model_json.get("params") or {}).items() if v is not None}
    return CameraModel.base(n_steps, effects).with_params(params)


def _figures(log: CameraLog, model: CameraModel, stderr: dict[str, float] | None = None) -> dict[str, Any]:
    from tracker.workbench.camera.predict import compare_camera

    cmp = compare_camera(log, model)
    return {
        "fit_percent": cmp.fit_percent,
        "fit_percent_increment": cmp.fit_percent_increment,
        "rms_deg": cmp.rms_deg,
        "horizon_s": cmp.horizon_s,
        "stderr": dict(stderr or {}),
    }


def first_version(label: str, text: str) -> dict[str, Any]:
    """Parse a camera log (DataError naming the line or column when bad) and fit the base camera
    model's speed per step to it: ``{"n", "dt_s", "model", "fit"}`` (``dt_s``: the command period)."""
    from tracker.workbench.camera.fit import fit_camera

    log = parse_camera_log(text, label)
    res = fit_camera(log, _base(log))
    fit = _figures(log, res.model, res.stderr)
    return plain({"n": log.n, "dt_s": log.period_s, "model": res.model.to_dict(), "fit": fit})


def refit(
    text: str, label: str, model_json: dict[str, Any], free: list[str] | None, add_effect: str | None
) -> dict[str, Any]:
    """Refit a stored camera model (``add_effect``: with that camera effect added, every free
    parameter refitted) into a new version: ``{"model", "fit"}``."""
    from tracker.workbench.camera.fit import fit_camera

    log = parse_camera_log(text, label)
    model = model_from_json(model_json, log)
    if add_effect is not None:
        model = model.with_effect(add_effect)
    res = fit_camera(log, model, free=tuple(free) if free else None)
    return plain({"model": res.model.to_dict(), "fit": _figures(log, res.model, res.stderr)})


def series(text: str, label: str) -> dict[str, Any]:
    """Decimated plot series of a stored camera log (degrees, speed steps)."""
    log = parse_camera_log(text, label)
    data: dict[str, Any] = series_deg(log.t_s, theta=log.theta_rad)
    data["speed_cmd"] = log.step[decimate_index(log.n)].tolist()
    return data


def _model(log: CameraLog, model_json: dict[str, Any] | None) -> CameraModel:
    # a camera log stored before camera versions existed has none: its model is the base one
    return _base(log) if model_json is None else model_from_json(model_json, log)


def compare(
    text: str, label: str, model_json: dict[str, Any] | None, horizon_s: float | None
) -> dict[str, Any]:
    """A camera model against the log: k-step fit, RMS, error by regime, plot series."""
    from tracker.workbench.camera.predict import compare_camera

    log = parse_camera_log(text, label)
    cmp = compare_camera(log, _model(log, model_json), horizon_s)
    out = cmp.to_dict()
    k = cmp.horizon_rows
    idx = np.arange(k, log.n)  # errors_rad[i] is the error of the k-step prediction ending at row k + i
    measured = log.theta_rad[idx]
    out["series"] = series_deg(
        log.t_s[idx], measured=measured, model=measured - cmp.errors_rad, residual=cmp.errors_rad
    )
    return plain(out)


def diagnose(
    text: str, label: str, model_json: dict[str, Any] | None, horizon_s: float | None = None
) -> dict[str, Any]:
    """Rank the camera effects a camera model lacks: fit, RMS, verdict, candidates."""
    from tracker.workbench.camera.diagnose import diagnose_camera

    log = parse_camera_log(text, label)
    return plain(diagnose_camera(log, _model(log, model_json), horizon_s).to_dict())
