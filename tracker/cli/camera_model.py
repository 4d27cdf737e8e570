"""``tracker model compare|fit|diagnose`` on a camera log (a ``speed_cmd`` column): the camera
workbench's side of the command, reached from :mod:`tracker.cli.model`'s dispatch point.

``--effects`` names camera effects (latency, speed_table, acceleration, backlash,
quantization), ``--set`` camera parameters (``latency.seconds=0.1``,
``speed_table.positive.3=0.05``, ...), ``--horizon`` the prediction horizon (default 0.5 s);
``--axis`` is accepted and not used (a camera log is one axis), ``--gain`` is refused.
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

from tracker.errors import ConfigError


def _clean(v: Any) -> Any:  # noqa: ANN401 - any JSON-ready value
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_clean(x) for x in v]
    return v


def _model(args: argparse.Namespace, n_steps: int) -> Any:  # noqa: ANN401 - a CameraModel
    from tracker.workbench.camera.model import CameraModel

    if getattr(args, "gain", None) is not None:
        raise ConfigError("--gain is for a voltage-driven axis; this is a camera log (speed_cmd)")
    effects = tuple(e.strip() for e in (args.effects or "").split(",") if e.strip())
    model = CameraModel.base(n_steps, effects)
    values: dict[str, float] = {}
    for item in args.set or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"--set {item!r}: expected NAME=VALUE, e.g. latency.seconds=0.1")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"--set {item!r}: {value!r} is not a number") from None
    return model.with_params(values) if values else model


def run(args: argparse.Namespace, command: str) -> int:
    """Run ``command`` (compare, fit, diagnose) on the camera log ``args.data``."""
    from tracker.workbench.camera.diagnose import diagnose_camera
    from tracker.workbench.camera.fit import fit_camera
    from tracker.workbench.camera.log import read_camera_log
    from tracker.workbench.camera.predict import compare_camera

    log = read_camera_log(args.data)
    model = _model(args, log.max_step)
    head = (
        f"{log.source}: camera log, {log.n} rows at {1 / log.period_s:.1f} Hz, steps up to {log.max_step}; "
        f"model: base{''.join(' + ' + e for e in model.effects)}"
    )
    if command == "compare":
        res: Any = compare_camera(log, model, args.horizon)
        lines = [
            head,
            f"k-step fit {res.fit_percent_increment:.2f} % ({res.horizon_rows} rows = "
            f"{res.horizon_s:.2f} s ahead), RMS {res.rms_deg:.4f}° (quantization floor "
            f"{res.quantization_floor_deg:.4f}°)",
            "error by regime:",
        ]
        lines += [
            f"  {k:<13} {r.fraction_of_time * 100:5.1f} % of time  "
            f"{r.share_of_error_percent:5.1f} % of error  "
            f"concentration {r.concentration:4.1f}"
            for k, r in res.regimes.items()
        ]
    elif command == "fit":
        free = tuple(f.strip() for f in (getattr(args, "free", None) or "").split(",") if f.strip()) or None
        res = fit_camera(log, model, horizon_s=args.horizon, free=free)
        lines = [head, f"k-step fit {res.fit_percent_increment:.2f} %, RMS {res.rms_deg:.4f}°", "parameters:"]
        lines += [
            f"  {n:<28} {v:.6g} ± {res.stderr.get(n, float('nan')):.2g}"
            for n, v in res.model.params().items()
        ]
        if any(res.unobserved_steps.values()):
            lines.append(f"steps not in the log (interpolated): {res.unobserved_steps}")
    else:
        res = diagnose_camera(log, model, args.horizon)
        lines = [
            head,
            f"k-step fit {res.fit_percent:.2f} %, RMS {res.rms_deg:.4f}°",
            f"verdict: {res.verdict or 'none (nothing significant is missing)'}",
            "",
        ]
        for i, c in enumerate(res.candidates, 1):
            lines.append(f"{i}. {c.effect}{'  [significant]' if c.significant else ''}")
            lines.append(f"   {c.evidence}")
        lines += ["", *res.notes]
    print(json.dumps(_clean(res.to_dict())) if args.json else "\n".join(lines))
    return 0
