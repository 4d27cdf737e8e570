"""``tracker model``: compare a model with a measurement, refit it, convert EMPS data (and diagnose).

::

    tracker model compare DATA.csv --axis pan|tilt [--effects a,b] [--gain K] [--json]
    tracker model fit     DATA.csv --axis pan|tilt [--effects a,b] [--gain K] [--json]
                          [--workspace DIR | --db PATH] [--plot F.png]
    tracker model history DATA.csv [--workspace DIR | --db PATH] [--plot F.png]
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
from tracker.workbench.compare.compare import DEFAULT_REPLICAS, CompareResult, compare_model
from tracker.workbench.compare.consistency import ResidualVerdict
from tracker.workbench.fit.fit import FitResult, fit_model
from tracker.workbench.fit.uncertainty import parameter_certainty
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


def format_compare(meas: Measurement, model: AxisModel, res: CompareResult, origin: str = "") -> str:
    """The comparison as a person reads it."""
    how = (
        f"{res.horizon_s * 1e3:.0f} ms ahead (k-step: each sample predicted from the state "
        f"{res.horizon_s * 1e3:.0f} ms before with the measured command)"
        if res.horizon_s
        else "free simulation of the whole run"
    )
    lines = [
        _header(meas, model),
        *([origin] if origin else []),
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
        f"input–residual correlation peaks at {ra.xcorr_peak_lag_s * 1e3:.0f} ms "
        f"({ra.xcorr_peak:+.2f}, bound ±{ra.xcorr_bound:.2f})"
    )
    if res.verdict is not None:
        lines += ["", *format_verdict(res.verdict)]
    if res.mode == "free":
        lines += [
            "",
            "free simulation: the axis integrates, so one simulation of the whole run drifts away on "
            "the smallest torque error and its fit falls far below 0 % even for a good model; read "
            "the k-step figure (the default, --mode k_step).",
        ]
    return "\n".join(lines)


def format_verdict(v: ResidualVerdict) -> list[str]:
    """The residual test as a person reads it: verdict, why, and the regimes against their band."""
    import textwrap

    head = (
        "RESIDUAL TEST: consistent with a right model" if v.consistent else "RESIDUAL TEST: model error left"
    )
    out = [head]
    out += textwrap.wrap(v.explanation(), 100, initial_indent="  ", subsequent_indent="  ")
    out.append(f"  {'regime':<12} {'RMS rad':>10} {'right model':>12} {'bound':>10}  ")
    for name, c in v.regimes.items():
        out.append(
            f"  {name:<12} {c.measured:10.3g} {c.expected:12.3g} {c.bound:10.3g}  {'ok' if c.ok else 'ABOVE'}"
        )
    return out


def format_fit(meas: Measurement, res: FitResult) -> str:
    """The fit as a person reads it."""
    lines = [
        _header(meas, res.model),
        f"fit {res.fit_percent:.3f} %   increment fit {res.fit_percent_increment:.2f} %   "
        f"RMS {res.rms_deg:.4g} deg   "
        f"({res.method}, horizon {res.horizon_s * 1e3:.0f} ms"
        + (
            f", fitted over {res.fit_horizon_s * 1e3:.0f} ms windows (coarse encoder)"
            if res.fit_horizon_s > res.horizon_s * (1 + 1e-9)
            else ""
        )
        + f", {res.n_evaluations} evaluations, "
        f"{'converged' if res.converged else 'NOT converged'}, {res.elapsed_s:.2f} s)",
        "",
        f"{'parameter':<28} {'value':>12} {'± stderr':>11} {'rel.':>6} {'start':>12}  unit",
    ]
    cert = {c.name: c for c in parameter_certainty(res.params, res.stderr, res.correlated, res.upper_bounds)}
    for k, v in res.params.items():
        se = res.stderr.get(k)
        c = cert.get(k)
        se_txt = f"{se:11.3g}" if se is not None else f"{'fixed':>11}"
        rel_txt = (
            f"{100 * c.relative_stderr:5.1f}%"
            if c is not None and math.isfinite(c.relative_stderr)
            else " " * 6
        )
        flag = "  POORLY DETERMINED" if c is not None and c.poorly_determined else ""
        start = res.start_params.get(k, v)
        lines.append(f"{k:<28} {v:12.5g} {se_txt} {rel_txt} {start:12.5g}  {get_param(k).unit}{flag}")
    poor = [c for c in cert.values() if c.poorly_determined]
    if poor:
        lines += ["", "poorly determined by this run (and the experiment that pins it):"]
        for c in poor:
            lines.append(f"  {c.name}: {c.reason}")
            if c.experiment:
                lines.append(f"    → {c.experiment}")
    lines += [f"warning: {w}" for w in res.warnings]
    return "\n".join(lines)


def compare_start(meas: Measurement, model: AxisModel, args: argparse.Namespace) -> tuple[AxisModel, str]:
    """The model ``compare`` sets against the data, and where its parameters come from.

    An axis preset's numbers describe the seed's mount, not the axis in the log (the EMPS axis
    weighs 95 kg where the pan preset has J = 0.002 kg·m²): predicted with them, the first
    figure is thousands of percent below zero and says nothing. So unless ``--preset`` (or a
    ``--set``), the parameters are the data's own linear inverse-dynamics estimate — what
    ``fit`` starts from — and the output says so.
    """
    if args.preset or args.set:
        return model, "parameters: as given (preset and --set)"
    start = fit_model(meas, model, method="inverse_dynamics")
    return (
        start.model,
        "parameters: estimated from this log by inverse dynamics (`tracker model fit` refines them)",
    )


@_guard
def run_compare(args: argparse.Namespace) -> int:
    """``tracker model compare``."""
    if is_camera_log_file(args.data):  # dispatch: a camera log goes to the camera workbench
        return camera_model.run(args, "compare")
    meas = read_log(args.data)
    model, origin = compare_start(meas, model_from_args(args), args)
    res = compare_model(meas, model, horizon_s=args.horizon, mode=args.mode, replicas=args.replicas)
    if args.json:
        print(_json({**res.to_dict(), "parameters": origin, "params": dict(model.params)}))
    else:
        print(format_compare(meas, model, res, origin))
    if args.plot:
        from tracker.cli.model_history import write_plot

        write_plot(args.plot, res, [], f"{meas.source}: {origin}")
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
    from tracker.cli.model_history import record_version, versions_in, write_plot

    certainty = [
        c.to_dict() for c in parameter_certainty(res.params, res.stderr, res.correlated, res.upper_bounds)
    ]
    compared = None
    if (args.plot or not args.no_keep) and args.replicas > 0:
        # the residual test of the fitted model: its error budget and the pictures
        compared = compare_model(meas, res.model, horizon_s=args.horizon, replicas=args.replicas)
    extra = {"certainty": certainty, "converged": bool(res.converged), "free": list(res.free)}
    kept = [] if args.no_keep else record_version(args, meas, res, compared, extra)
    if args.json:
        print(_json({**res.to_dict(), "certainty": certainty}))
    else:
        print(format_fit(meas, res))
        print("\n".join(kept))
    if args.plot:
        shown = [] if args.no_keep else versions_in(args, meas)
        pictured = compared or compare_model(meas, res.model, horizon_s=args.horizon)
        write_plot(args.plot, pictured, shown, meas.source)
    return 0


@_guard
def run_history(args: argparse.Namespace) -> int:
    """``tracker model history`` (tracker/cli/model_history.py)."""
    from tracker.cli.model_history import run_history as history

    return history(args)


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
        fit = f"current model: fit {d.fit_percent:.3f} % (k-step)"
        if d.refit_fit_percent is not None:
            fit = (
                f"current model: fit {d.refit_fit_percent:.3f} % (k-step) with its base parameters "
                f"refitted to this log ({d.fit_percent:.3f} % as given: they are far from this data)"
            )
        lines = [_header(meas, model), fit, verdict, ""]
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
    from tracker.cli.model_history import add_plot_option, add_store_options

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
    c.add_argument(
        "--replicas",
        type=int,
        default=DEFAULT_REPLICAS,
        metavar="N",
        help=f"simulated replicas for the residual test (default {DEFAULT_REPLICAS}; 0: skip it)",
    )
    c.add_argument(
        "--preset",
        action="store_true",
        help="compare the axis preset's parameters as they are (default: estimate them from the log)",
    )
    add_plot_option(c)
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
    add_store_options(f)
    f.add_argument("--no-keep", action="store_true", help="do not keep the fit as a version")
    f.add_argument(
        "--replicas",
        type=int,
        default=DEFAULT_REPLICAS,
        metavar="N",
        help="replicas for the kept version's error budget (0: keep it without one)",
    )
    f.set_defaults(func=run_fit)

    h = sub.add_parser("history", help="the versions kept for a log: the error falling, the error budget")
    h.add_argument("data", metavar="DATA.csv", nargs="?", default=None)
    add_store_options(h)
    h.add_argument(
        "--measurement", type=int, default=None, metavar="ID", help="with --db: the console's measurement #ID"
    )
    h.add_argument(
        "--replicas", type=int, default=DEFAULT_REPLICAS, metavar="N", help="replicas for the floor (0: none)"
    )
    h.add_argument("--json", action="store_true", help="print one JSON object")
    h.set_defaults(func=run_history)

    e = sub.add_parser("emps-convert", help="convert an EMPS .mat file to a CSV log")
    e.add_argument("mat", metavar="MAT", help="DATA_EMPS.mat or DATA_EMPS_PULSES.mat")
    e.add_argument("out", metavar="OUT.csv", help="where to write the log")
    e.set_defaults(func=run_emps_convert)

    _register_diagnose(sub)


__all__ = ["format_compare", "format_fit", "model_from_args", "register", "run_compare", "run_fit"]
