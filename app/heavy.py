"""The heavy work of the workbench and the practice rig, as pure functions of plain values.

They run in the worker processes of app/work.py, never on the event loop that runs the engine:
arguments are the stored CSV text and model JSON, results are JSON-ready dicts, and the routes
read and write the database. The semantics are those of ``tracker model ...``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from app.modelio import decimate_index, model_from_json, model_to_json, plain, series_deg
from tracker.plant.effects import get_effect
from tracker.plant.model import AxisModel
from tracker.workbench.compare.compare import compare_model
from tracker.workbench.measurements.data import Measurement, parse_log


def fit_summary(
    meas: Measurement,
    model: AxisModel,
    extra: dict[str, Any] | None = None,
    earlier: list[tuple[str, float]] | None = None,
    change: str = "base",
) -> dict[str, Any]:
    """The figures a version keeps: compare fit, RMS error, its error budget after the versions
    ``earlier`` ((label, budget RMS deg), oldest first; tracker/workbench/budget.py), and the
    fitter's output when given."""
    from tracker.workbench.budget import error_budget
    from tracker.workbench.compare.compare import DEFAULT_REPLICAS

    cmp = compare_model(meas, model, replicas=DEFAULT_REPLICAS)
    out: dict[str, Any] = {
        "fit_percent": cmp.fit_percent,
        "fit_percent_increment": cmp.fit_percent_increment,
        "rms_deg": cmp.rms_deg,
        "horizon_s": cmp.horizon_s,
    }
    budget = error_budget(meas, model, earlier or [], change, compared=cmp)
    if budget is not None:
        out["budget"] = budget.to_dict()
    out.update(extra or {})
    return plain(out)


def fitter_extra(res: Any) -> dict[str, Any]:  # noqa: ANN401 - a FitResult
    """What a version keeps from the fitter: parameters with standard errors, convergence."""
    from tracker.workbench.fit.uncertainty import parameter_certainty

    return {
        "params": dict(res.params),
        "stderr": dict(res.stderr),
        "certainty": [
            c.to_dict() for c in parameter_certainty(res.params, res.stderr, res.correlated, res.upper_bounds)
        ],
        "converged": bool(res.converged),
        "free": list(res.free),
    }


def first_version(
    label: str, axis: str, text: str, gain_nm_per_v: float | None = None, effects: tuple[str, ...] = ()
) -> dict[str, Any]:
    """Parse a log and fit the axis' base model (plus ``effects``, K overridden by
    ``gain_nm_per_v``) to it: ``{"n", "dt_s", "model", "fit"}``. DataError/ConfigError when bad."""
    from tracker.workbench.fit.fit import fit_model

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
    from tracker.workbench.compare.compare import DEFAULT_REPLICAS

    meas = parse_log(text, label)
    cmp = compare_model(
        meas,
        model_from_json(model_json),
        horizon_s=horizon_s,
        mode=mode,  # type: ignore[arg-type]
        replicas=DEFAULT_REPLICAS if mode == "k_step" else 0,
    )
    out = cmp.to_dict(arrays=False)
    out["residual_analysis"] = cmp.residuals.to_dict(arrays=True)
    if cmp.verdict is not None:
        out["residual_verdict"] = cmp.verdict.to_dict(arrays=True)
    out["series"] = series_deg(
        cmp.t_s, measured=cmp.theta_meas_rad, model=cmp.theta_pred_rad, residual=cmp.residual_rad
    )
    return plain(out)


def diagnose(text: str, label: str, model_json: dict[str, Any]) -> dict[str, Any]:
    """The missing effects of a model version, ranked, with the residual test of the version and
    how the two verdicts fit together (``residual_verdict``, ``agreement``)."""
    from tracker.workbench.compare.compare import DEFAULT_REPLICAS
    from tracker.workbench.compare.consistency import agreement
    from tracker.workbench.diagnose.diagnose import diagnose as rank

    meas = parse_log(text, label)
    model = model_from_json(model_json)
    out = rank(meas, model).to_dict()
    verdict = compare_model(meas, model, replicas=DEFAULT_REPLICAS).verdict
    if verdict is not None:
        out["residual_verdict"] = verdict.to_dict()
        out["agreement"] = agreement(verdict, out.get("verdict"))  # type: ignore[arg-type]
    return plain(out)


def refit(
    text: str,
    label: str,
    axis: str,
    model_json: dict[str, Any],
    free: list[str] | None = None,
    add_effect: str | None = None,
    change: str = "refit",
    earlier: list[tuple[str, float]] | None = None,
) -> dict[str, Any]:
    """Refit a version's parameters (``free`` only, when given), or add ``add_effect`` and refit
    every parameter (K fixed): ``{"model", "fit"}`` of the new version (made by ``change``), its error
    budget after ``earlier``."""
    from tracker.workbench.fit.fit import fit_model

    meas = parse_log(text, label)
    model = model_from_json(model_json)
    if add_effect is not None:
        get_effect(add_effect)
        model = model.with_effect(add_effect)
    res = fit_model(meas, model, free=free) if free else fit_model(meas, model)
    fit = fit_summary(meas, res.model, fitter_extra(res), earlier, change)
    return {"model": model_to_json(res.model, axis), "fit": fit}


def practice_run(
    truth_json: dict[str, Any], axis: str, kind: str, duration_s: float, seed: int, label: str
) -> dict[str, Any]:
    """Record one experiment on the practice rig and fit its first version:
    ``{"csv", "n", "dt_s", "model", "fit"}``."""
    from app.experiments import record_experiment
    from tracker.workbench.measurements.data import format_log

    meas = record_experiment(model_from_json(truth_json), axis, kind, duration_s, seed)
    text = format_log(meas)
    return {"csv": text, **first_version(label, axis, text)}


def model_check(
    axis: str,
    recent: tuple[Any, Any, Any] | None,
    candidate_json: dict[str, Any],
    current_json: dict[str, Any],
) -> dict[str, Any]:
    """Does the candidate model predict the axis's recent motion (``recent``: t s, u V, θ rad
    arrays, or None)? ``ModelCheck.to_dict()`` (SI units; tracker.model_check)."""
    from tracker.model_check import check_model

    meas = None if recent is None else Measurement(*recent, f"engine (recent):{axis}")
    check = check_model(axis, meas, model_from_json(candidate_json), model_from_json(current_json))
    return check.to_dict()


def result_json(value: Any) -> Any:  # noqa: ANN401 - any result object in, JSON-ready value out
    """JSON-ready copy of a result object (dataclass, numpy values, nested containers)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: result_json(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if hasattr(value, "tolist"):
        return result_json(value.tolist())
    if isinstance(value, dict):
        return {str(k): result_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [result_json(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def gain_margins(model_json: dict[str, Any], gains: Any, floor_deg: float) -> dict[str, Any]:  # noqa: ANN401
    """Phase/gain margins and stability of ``gains`` on the model (DesignReport as JSON), and
    ``acceptable``: stable with at least ``floor_deg`` of phase margin."""
    from tracker.control.design import check_gains

    out: dict[str, Any] = result_json(check_gains(model_from_json(model_json), gains, floor_deg))
    pm = out.get("phase_margin_deg")
    out["acceptable"] = bool(out.get("stable")) and pm is not None and pm >= floor_deg
    return out


def step_prediction(
    model_json: dict[str, Any],
    gains: Any,  # noqa: ANN401 - a ControllerGains
    amplitude_deg: float,
    duration_s: float,
    shaping: Any = None,  # noqa: ANN401 - TrajectoryLimits or None
) -> dict[str, Any]:
    """Predicted step response, as {"t_s": [...], "angle_deg": [...], figures} (decimated): the
    engine's full nonlinear loop on the model, through ``shaping`` when given (what the rig does)."""
    from tracker.control.design import predicted_step_response

    res = predicted_step_response(
        model_from_json(model_json), gains, math.radians(amplitude_deg), duration_s, shaping=shaping
    )
    step = max(1, len(res.t_s) // 400)
    out: dict[str, Any] = result_json(
        {
            "rise_time_s": res.rise_time_s,
            "overshoot_percent": res.overshoot_percent,
            "settling_time_s": res.settling_time_s,
            "peak_command_v": res.peak_command_v,
            "t_s": res.t_s[::step].round(5),
            "angle_deg": (res.theta_rad[::step] * 180.0 / math.pi).round(4),
            "amplitude_deg": amplitude_deg,
        }
    )
    return out


def gain_preview(
    model_json: dict[str, Any],
    current: Any,  # noqa: ANN401 - ControllerGains
    candidate: Any,  # noqa: ANN401 - ControllerGains
    amplitude_deg: float,
    duration_s: float,
    shaping: Any,  # noqa: ANN401 - TrajectoryLimits or None
    floor_deg: float,
) -> dict[str, Any]:
    """Margins of ``candidate`` and the predicted steps of both gain sets."""
    return {
        "margins": gain_margins(model_json, candidate, floor_deg),
        "step": step_prediction(model_json, candidate, amplitude_deg, duration_s, shaping),
        "current_step": step_prediction(model_json, current, amplitude_deg, duration_s, shaping),
    }


def warm_up() -> None:
    """Import what the heavy work needs (a new worker's first request is then not slower)."""
    import tracker.control.design
    import tracker.workbench.diagnose.diagnose
    import tracker.workbench.fit.fit  # noqa: F401
