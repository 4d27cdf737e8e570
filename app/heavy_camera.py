"""The workbench's heavy work on a PTZ camera log (CSV ``t,speed_cmd,theta``), as pure functions
of plain values run in the worker processes of app/work.py (like app/heavy.py for DC logs).

A camera log is checked against the camera model of tracker/workbench/camera/ (latency, speed
table, acceleration, backlash, quantization), as ``tracker model compare|diagnose`` does on one.
Its first model is the base camera model (linear speed table, no latency), not a stored version:
compare and diagnose run on that model, as the command line does without ``--effects``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from app.modelio import decimate_index, plain, series_deg
from tracker.workbench.camera.log import CameraLog, is_camera_log, parse_camera_log
from tracker.workbench.camera.model import CameraModel

KIND = "camera"


def is_camera(text: str) -> bool:
    """True when the stored CSV is a camera log (its header has ``speed_cmd``)."""
    return is_camera_log(text)


def _base(log: CameraLog) -> CameraModel:
    return CameraModel.base(log.max_step)


def first_summary(label: str, text: str) -> dict[str, Any]:
    """Parse a camera log (DataError naming the line or column when bad) and compare the base
    camera model with it: ``{"n", "dt_s", "fit"}`` (``dt_s``: the command period)."""
    from tracker.workbench.camera.predict import compare_camera

    log = parse_camera_log(text, label)
    cmp = compare_camera(log, _base(log))
    fit = {
        "fit_percent": cmp.fit_percent,
        "fit_percent_increment": cmp.fit_percent_increment,
        "rms_deg": cmp.rms_deg,
        "horizon_s": cmp.horizon_s,
    }
    return plain({"n": log.n, "dt_s": log.period_s, "fit": fit})


def series(text: str, label: str) -> dict[str, Any]:
    """Decimated plot series of a stored camera log (degrees, speed steps)."""
    log = parse_camera_log(text, label)
    data: dict[str, Any] = series_deg(log.t_s, theta=log.theta_rad)
    data["speed_cmd"] = log.step[decimate_index(log.n)].tolist()
    return data


def compare(text: str, label: str, horizon_s: float | None) -> dict[str, Any]:
    """The base camera model against the log: k-step fit, RMS, error by regime, plot series."""
    from tracker.workbench.camera.predict import compare_camera

    log = parse_camera_log(text, label)
    cmp = compare_camera(log, _base(log), horizon_s)
    out = cmp.to_dict()
    k = cmp.horizon_rows
    idx = np.arange(k, log.n)  # errors_rad[i] is the error of the k-step prediction ending at row k + i
    measured = log.theta_rad[idx]
    out["series"] = series_deg(
        log.t_s[idx], measured=measured, model=measured - cmp.errors_rad, residual=cmp.errors_rad
    )
    return plain(out)


def diagnose(text: str, label: str, horizon_s: float | None = None) -> dict[str, Any]:
    """Rank the camera effects the base camera model lacks: fit, RMS, verdict, candidates."""
    from tracker.workbench.camera.diagnose import diagnose_camera

    log = parse_camera_log(text, label)
    return plain(diagnose_camera(log, _base(log), horizon_s).to_dict())
