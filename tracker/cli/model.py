"""``tracker model``: compare a model with a measurement, refit it, convert EMPS data (and diagnose).

::

    tracker model compare DATA.csv --axis pan|tilt [--effects a,b] [--gain K] [--json]
    tracker model fit     DATA.csv --axis pan|tilt [--effects a,b] [--gain K] [--json]
    tracker model emps-convert DATA_EMPS.mat OUT.csv

Every problem with the input becomes one ``error: ...`` line naming the line, column or option,
and exit code 2 (never a traceback).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from tracker.cli import camera_model
from tracker.errors import ConfigError, TrackerError
from tracker.plant.effects import get_param
from tracker.plant.model import AxisModel
from tracker.workbench.camera.log import is_camera_log_file
from tracker.workbench.compare.compare import CompareResult, compare_model
from tracker.workbench.fit.fit import FitResult, fit_model
from tracker.workbench.measurements.data import Measurement, read_log


def _effects(text: str | None) -> tuple[str, ...]:
    if not text:
        return ()
    return tuple(e.strip() for e in text.split(",") if e.strip())


def _overrides(items: list[str] | None) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"--set {item!r}: expected NAME=VALUE, e.g. inertia.J=0.003")
        prm = get_param(name.strip())
        try:
            v = float(value)
        except ValueError:
            raise ConfigError(f"--set {item!r}: {value!r} is not a number") from None
        out[name.strip()] = prm.check(v, f"--set {name.strip()}")
    return out


def model_from_args(args: argparse.Namespace) -> AxisModel:
    """The model the options describe: the axis preset, ``--effects``, ``--gain``, ``--set``."""
    gain = args.gain
    if gain is not None and not (math.isfinite(gain) and gain > 0):
        raise ConfigError(f"--gain must be a positive number (N·m/V, or N/V for a linear axis), got {gain!r}")
    return AxisModel.for_axis(args.axis, _effects(args.effects), _overrides(args.set), gain_nm_per_v=gain)


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", metavar="DATA.csv", help="measurement log with columns t (s), u (V), theta (rad)")
    p.add_argument(
        "--axis", required=True, choices=("pan", "tilt"), help="seed defaults for K and starting values"
    )
    p.add_argument("--effects", default="", help="effects added to the base model, comma-separated")
    p.add_argument(
        "--gain", type=float, default=None, help="amplifier gain K (N·m/V, or N/V for a linear axis)"
    )
    p.add_argument(
        "--set", action="append", metavar="NAME=VALUE", help="set a parameter, e.g. inertia.J=0.003"
    )
    p.add_argument(
        "--horizon", type=float, default=None, metavar="S", help="prediction horizon, s (default 0.03)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _guard(fn: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """Turn every foreseeable failure into one error line and exit code 2."""

    def run(args: argparse.Namespace) -> int:
        try:
            return fn(args)
        except TrackerError:
            raise
        except (ValueError, ArithmeticError, np.linalg.LinAlgError, OSError) as exc:
            print(f"error: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 2

    return run


def _json(obj: Any) -> str:
    def clean(v: Any) -> Any:
        if isinstance(v, float) and not math.isfinite(v):
            return None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v

    return json.dumps(clean(obj))


def _header(meas: Measurement, model: AxisModel) -> str:
    effects = "".join(f" + {e}" for e in model.effects)
    return (
        f"{meas.source}: {meas.n} samples, {meas.t_s[-1] - meas.t_s[0]:.2f} s at {meas.dt_s * 1e3:.3g} ms; "
        f"model: base{effects} (K = {model.gain_nm_per_v:.6g})"
    )


def format_compare(meas: Measurement, model: AxisModel, res: CompareResult) -> str:
    """The comparison as a person reads it."""
    how = f"{res.horizon_s * 1e3:.0f} ms ahead" if res.horizon_s else "free simulation"
    lines = [
        _header(meas, model),
        f"prediction: {how}",
        f"fit {res.fit_percent:.3f} %   increment fit {res.fit_percent_increment:.2f} %   "
        f"RMS {res.rms_deg:.4g} deg",
        "",
        f"{'regime':<12} {'time %':>7} {'error %':>8} {'concentr.':>9} {'RMS deg':>10}",
    ]
    for name, r in res.regimes.items():
        lines.append(
            f"{name:<12} {100 * r.fraction_of_time:7.1f} {r.share_of_error_percent:8.1f} "
            f"{r.concentration:9.2f} {r.rms_deg:10.4g}"
        )
    lines += ["", "error by position:"]
    for label, r in res.breakdown.position_bins:
        lines.append(
            f"  {label:<24} {100 * r.fraction_of_time:6.1f} % of time  "
            f"{r.share_of_error_percent:6.1f} % of error"
        )
    lines.append(
        "residual power by frequency: "
        + ", ".join(f"{b} {p:.0f} %" for b, p in res.breakdown.frequency_bands)
    )
    ra = res.residuals
    lines.append(
        f"residual whiteness: {100 * ra.autocorr_outside_fraction:.0f} % of lags outside the 99 % bound "
        f"(±{ra.autocorr_bound:.3f}); input–residual correlation peaks at {ra.xcorr_peak_lag_s * 1e3:.0f} ms "
        f"({ra.xcorr_peak:+.2f}, bound ±{ra.xcorr_bound:.2f})"
    )
    return "\n".join(lines)


def format_fit(meas: Measurement, res: FitResult) -> str:
    """The fit as a person reads it."""
    lines = [
        _header(meas, res.model),
        f"fit {res.fit_percent:.3f} %   increment fit {res.fit_percent_increment:.2f} %   "
        f"RMS {res.rms_deg:.4g} deg   "
        f"({res.method}, horizon {res.horizon_s * 1e3:.0f} ms, {res.n_evaluations} evaluations, "
        f"{'converged' if res.converged else 'NOT converged'}, {res.elapsed_s:.2f} s)",
        "",
        f"{'parameter':<28} {'value':>12} {'± stderr':>11} {'start':>12}  unit",
    ]
    for k, v in res.params.items():
        se = res.stderr.get(k)
        se_txt = f"{se:11.3g}" if se is not None else f"{'fixed':>11}"
        start = res.start_params.get(k, v)
        lines.append(f"{k:<28} {v:12.5g} {se_txt} {start:12.5g}  {get_param(k).unit}")
    lines += [f"warning: {w}" for w in res.warnings]
    return "\n".join(lines)


@_guard
def run_compare(args: argparse.Namespace) -> int:
    """``tracker model compare``."""
    if is_camera_log_file(args.data):  # dispatch: a camera log goes to the camera workbench
        return camera_model.run(args, "compare")
    meas = read_log(args.data)
    model = model_from_args(args)
    res = compare_model(meas, model, horizon_s=args.horizon, mode=args.mode)
    if args.json:
        print(_json(res.to_dict()))
    else:
        print(format_compare(meas, model, res))
    return 0


@_guard
def run_fit(args: argparse.Namespace) -> int:
    """``tracker model fit``."""
    if is_camera_log_file(args.data):
        return camera_model.run(args, "fit")
    meas = read_log(args.data)
    model = model_from_args(args)
    free = _effects(args.free) or None
    if free:
        for k in free:
            get_param(k)
    res = fit_model(
        meas, model, free=free, horizon_s=args.horizon, fit_gain=args.fit_gain, method=args.method
    )
    if args.json:
        print(_json(res.to_dict()))
    else:
        print(format_fit(meas, res))
    return 0


@_guard
def run_emps_convert(args: argparse.Namespace) -> int:
    """``tracker model emps-convert``."""
    from tracker.workbench.measurements.emps import convert_emps

    meas = convert_emps(args.mat, args.out)
    print(f"wrote {args.out}: {meas.n} samples (t s, u = vir V, theta = qm m); use --gain 35.15 (N/V)")
    return 0


def _register_diagnose(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Placeholder for ``tracker model diagnose`` (the diagnosis engineer fills this in).

    ---- DIAGNOSE: owned by the diagnosis engineer; edit only inside this function ----
    Use :func:`_add_common` for the shared options and :func:`model_from_args` for the model.

    ``tracker model diagnose DATA.csv --axis pan|tilt [--effects a,b] [--gain K] [--json]``:
    ranks every effect the model lacks; ``--json`` prints the contract object
    ``{"fit_percent", "verdict", "candidates": [...]}`` (plus ``notes``).
    """
    import textwrap

    from tracker.workbench.diagnose.diagnose import Candidate, Diagnosis, diagnose

    def card(i: int, c: Candidate, width: int = 100) -> list[str]:
        mark = "SIGNIFICANT" if c.significant else (c.finding or "not significant")
        out = [f"{i}. {c.effect}  —  {mark}; fit with it {c.fit_percent:.3f} %"]
        for k, v in c.params.items():
            se = c.stderr.get(k)
            se_txt = f" ± {se:.3g}" if se is not None and math.isfinite(se) else ""
            out.append(f"     {k} = {v:.5g}{se_txt} {get_param(k).unit}")
        out += textwrap.wrap(c.evidence, width, initial_indent="     ", subsequent_indent="     ")
        if c.confused_with:
            out.append(f"     looks like: {', '.join(c.confused_with)}")
        if c.significant and c.experiment:
            out += textwrap.wrap(
                "to confirm: " + c.experiment, width, initial_indent="     ", subsequent_indent="     "
            )
        return out

    def format_diagnosis(meas: Measurement, model: AxisModel, d: Diagnosis) -> str:
        verdict = (
            f"VERDICT: the model is missing {d.verdict}"
            if d.verdict
            else "VERDICT: nothing significant is missing"
        )
        lines = [_header(meas, model), f"current model: fit {d.fit_percent:.3f} % (k-step)", verdict, ""]
        for i, c in enumerate(d.candidates, start=1):
            lines += card(i, c)
        if d.notes:
            lines += ["", "notes:"]
            for n in d.notes:
                lines += textwrap.wrap(n, 100, initial_indent="  - ", subsequent_indent="    ")
        lines.append(f"({d.elapsed_s:.2f} s)")
        return "\n".join(lines)

    @_guard
    def run_diagnose(args: argparse.Namespace) -> int:
        if is_camera_log_file(args.data):
            return camera_model.run(args, "diagnose")
        meas = read_log(args.data)
        model = model_from_args(args)
        d = diagnose(meas, model, horizon_s=args.horizon)
        print(_json(d.to_dict()) if args.json else format_diagnosis(meas, model, d))
        return 0

    d = sub.add_parser("diagnose", help="rank the effects the model lacks and name the missing one")
    _add_common(d)
    d.set_defaults(func=run_diagnose)


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add ``tracker model ...`` to the command line."""
    from tracker.cli import command_help

    p = subparsers.add_parser("model", help=command_help("model"))
    sub = p.add_subparsers(dest="model_command", metavar="SUBCOMMAND")
    sub.required = True

    c = sub.add_parser("compare", help="set a model against a measurement (fit %%, RMS, error by regime)")
    _add_common(c)
    c.add_argument(
        "--mode",
        choices=("k_step", "free"),
        default="k_step",
        help="k-step-ahead prediction or free simulation",
    )
    c.set_defaults(func=run_compare)

    f = sub.add_parser("fit", help="refit every free parameter in physical units")
    _add_common(f)
    f.add_argument("--free", default="", help="parameters to fit (default: all free ones), comma-separated")
    f.add_argument("--fit-gain", action="store_true", help="also fit K (then J is held)")
    f.add_argument(
        "--method",
        choices=("k_step", "inverse_dynamics"),
        default="k_step",
        help="k-step prediction error (default) or linear inverse-dynamics least squares",
    )
    f.set_defaults(func=run_fit)

    e = sub.add_parser("emps-convert", help="convert an EMPS .mat file to a CSV log")
    e.add_argument("mat", metavar="MAT", help="DATA_EMPS.mat or DATA_EMPS_PULSES.mat")
    e.add_argument("out", metavar="OUT.csv", help="where to write the log")
    e.set_defaults(func=run_emps_convert)

    _register_diagnose(sub)


__all__ = ["format_compare", "format_fit", "model_from_args", "register", "run_compare", "run_fit"]
