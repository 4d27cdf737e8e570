"""The heavy work of the workbench and the practice rig, as pure functions of plain values.

They run in the worker processes of app/work.py, never on the event loop that runs the engine:
arguments are the stored CSV text and model JSON, results are JSON-ready dicts, and the routes
read and write the database. The semantics are those of ``tracker model ...``.
"""

from __future__ import annotations

from typing import Any

from app.modelio import decimate_index, model_from_json, model_to_json, plain, series_deg
from tracker.plant.effects import get_effect
from tracker.plant.model import AxisModel
from tracker.workbench.compare import compare_model
from tracker.workbench.data import Measurement, parse_log


def fit_summary(meas: Measurement, model: AxisModel, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The figures a version keeps: compare fit, RMS error, and the fitter's output when given."""
    cmp = compare_model(meas, model)
    out = {
        "fit_percent": cmp.fit_percent,
        "fit_percent_increment": cmp.fit_percent_increment,
        "rms_deg": cmp.rms_deg,
        "horizon_s": cmp.horizon_s,
    }
    out.update(extra or {})
    return plain(out)


def fitter_extra(res: Any) -> dict[str, Any]:  # noqa: ANN401 - a FitResult
    """What a version keeps from the fitter: parameters with standard errors, convergence."""
    return {
        "params": dict(res.params),
        "stderr": dict(res.stderr),
        "converged": bool(res.converged),
        "free": list(res.free),
    }


def first_version(
    label: str, axis: str, text: str, gain_nm_per_v: float | None = None, effects: tuple[str, ...] = ()
) -> dict[str, Any]:
    """Parse a log and fit the axis' base model (plus ``effects``, K overridden by
    ``gain_nm_per_v``) to it: ``{"n", "dt_s", "model", "fit"}``. DataError/ConfigError when bad."""
    from tracker.workbench.fit import fit_model

    model = AxisModel.for_axis(axis, effects, gain_nm_per_v=gain_nm_per_v)
    meas = parse_log(text, label)
    res = fit_model(meas, model)
    return {
        "n": meas.n,
        "dt_s": meas.dt_s,
        "model": model_to_json(res.model, axis),
        "fit": fit_summary(meas, res.model, fitter_extra(res)),
    }


def measurement_series(text: str, label: str) -> dict[str, Any]:
    """Decimated plot series of a stored log (degrees, volts)."""
    meas = parse_log(text, label)
    data: dict[str, Any] = series_deg(meas.t_s, theta=meas.theta_rad)
    data["u_v"] = meas.u_v[decimate_index(meas.n)].round(5).tolist()
    return data


def compare(
    text: str, label: str, model_json: dict[str, Any], horizon_s: float | None, mode: str
) -> dict[str, Any]:
    """A model version set against the measurement, with residual analysis and plot series."""
    meas = parse_log(text, label)
    cmp = compare_model(meas, model_from_json(model_json), horizon_s=horizon_s, mode=mode)  # type: ignore[arg-type]
    out = cmp.to_dict(arrays=False)
    out["residual_analysis"] = cmp.residuals.to_dict(arrays=True)
    out["series"] = series_deg(
        cmp.t_s, measured=cmp.theta_meas_rad, model=cmp.theta_pred_rad, residual=cmp.residual_rad
    )
    return plain(out)


def diagnose(text: str, label: str, model_json: dict[str, Any]) -> dict[str, Any]:
    """The missing effects of a model version, ranked."""
    from tracker.workbench.diagnose import diagnose as rank

    return plain(rank(parse_log(text, label), model_from_json(model_json)).to_dict())


def refit(
    text: str,
    label: str,
    axis: str,
    model_json: dict[str, Any],
    free: list[str] | None = None,
    add_effect: str | None = None,
) -> dict[str, Any]:
    """Refit a version's parameters (``free`` only, when given), or add ``add_effect`` and refit
    every parameter (K fixed): ``{"model", "fit"}`` of the new version."""
    from tracker.workbench.fit import fit_model

    meas = parse_log(text, label)
    model = model_from_json(model_json)
    if add_effect is not None:
        get_effect(add_effect)
        model = model.with_effect(add_effect)
    res = fit_model(meas, model, free=free) if free else fit_model(meas, model)
    return {"model": model_to_json(res.model, axis), "fit": fit_summary(meas, res.model, fitter_extra(res))}


def practice_run(
    truth_json: dict[str, Any], axis: str, kind: str, duration_s: float, seed: int, label: str
) -> dict[str, Any]:
    """Record one experiment on the practice rig and fit its first version:
    ``{"csv", "n", "dt_s", "model", "fit"}``."""
    from app.experiments import record_experiment
    from tracker.workbench.data import format_log

    meas = record_experiment(model_from_json(truth_json), axis, kind, duration_s, seed)
    text = format_log(meas)
    return {"csv": text, **first_version(label, axis, text)}
