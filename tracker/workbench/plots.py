"""The console's workbench pictures as one PNG (``tracker model compare|fit|history --plot FILE.png``).

Panels: measured vs predicted angle; the residual with the band a right model leaves on this
run (± the simulated replicas' RMS, and their 99 % bound); the residual's autocorrelation inside
the replicas' envelope; error by regime against the right model's bound; and, for a history, the
RMS per version and the error budget as a stacked bar over versions. matplotlib comes with
python-control; this module (imported by the command line only for ``--plot``) switches it to the
Agg backend: no display is needed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tracker.errors import ConfigError
from tracker.workbench.compare.compare import CompareResult
from tracker.workbench.versions import ModelVersion

MAX_POINTS = 4000
BUDGET_COLOURS = {
    "quantization": "#adb5bd",
    "noise": "#ced4da",
    "load disturbance": "#dee2e6",
    "left": "#e8590c",
}
EFFECT_COLOURS = ("#1c7ed6", "#37b24d", "#7048e8", "#f59f00", "#0ca678", "#d6336c", "#1098ad")


def _pyplot() -> Any:  # noqa: ANN401 - the matplotlib.pyplot module
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _every(n: int) -> slice:
    return slice(None, None, max(1, math.ceil(n / MAX_POINTS)))


def _overlay(ax: Any, res: CompareResult) -> None:  # noqa: ANN401
    s = _every(res.t_s.size)
    ax.plot(res.t_s[s], np.degrees(res.theta_meas_rad[s]), color="#1c7ed6", lw=1.6, label="measured")
    ax.plot(res.t_s[s], np.degrees(res.theta_pred_rad[s]), "--", color="#e03131", lw=1.0, label="model")
    how = f"{res.horizon_s * 1e3:.0f} ms ahead" if res.horizon_s else "free run"
    ax.set(title=f"measured vs model ({how}): fit {res.fit_percent:.2f} %", xlabel="time (s)", ylabel="θ (°)")
    ax.legend(loc="best", fontsize=8)


def _residual(ax: Any, res: CompareResult) -> None:  # noqa: ANN401
    s = _every(res.t_s.size)
    ax.plot(res.t_s[s], np.degrees(res.residual_rad[s]), color="#6f42c1", lw=0.7, label="residual")
    v = res.verdict
    if v is not None:
        mean, bound = math.degrees(v.rms_rad.expected), math.degrees(v.rms_rad.bound)
        ax.axhspan(-mean, mean, color="#adb5bd", alpha=0.35, label=f"right model: ±{mean:.3g}° RMS")
        for sign in (1, -1):
            ax.axhline(sign * bound, color="#495057", ls=":", lw=0.8)
        word = "consistent with a right model" if v.consistent else "model error left"
        ax.set_title(
            f"residual: {math.degrees(v.rms_rad.measured):.3g}° RMS, {v.rms_rad.ratio:.2f}× — {word}"
        )
    else:
        ax.set_title(f"residual: {res.rms_deg:.3g}° RMS")
    ax.set(xlabel="time (s)", ylabel="residual (°)")
    ax.legend(loc="upper right", fontsize=8)


def _autocorr(ax: Any, res: CompareResult) -> None:  # noqa: ANN401
    r = res.residuals
    ax.plot(r.autocorr_lags_s, r.autocorr, color="#1c7ed6", lw=1.4, label="residual")
    if res.verdict is not None:
        band = res.verdict.autocorr_band
        ax.fill_between(
            r.autocorr_lags_s, band[0], band[1], color="#adb5bd", alpha=0.4, label="right model (replicas)"
        )
    ax.axhline(0, color="#868e96", lw=0.6)
    ax.set(title="residual autocorrelation", xlabel="lag (s)", ylabel="autocorr.")
    ax.legend(loc="upper right", fontsize=8)


def _regimes(ax: Any, res: CompareResult) -> None:  # noqa: ANN401
    names = [k for k, e in res.regimes.items() if e.samples > 0]
    rms = [res.regimes[k].rms_deg for k in names]
    y = np.arange(len(names))
    checks = res.verdict.regimes if res.verdict is not None else {}
    colours = ["#e8590c" if k in checks and not checks[k].ok else "#5c7cfa" for k in names]
    ax.barh(y, rms, color=colours)
    for i, k in enumerate(names):
        if k in checks:
            ax.plot([math.degrees(checks[k].bound)] * 2, [i - 0.4, i + 0.4], color="#212529", lw=1.5)
    ax.set_yticks(y, [k.replace("_", " ") for k in names])
    ax.invert_yaxis()
    ax.set(title="error by regime (| = right model's bound)", xlabel="RMS error (°)")


def _versions(ax: Any, versions: Sequence[ModelVersion]) -> None:  # noqa: ANN401
    x = np.arange(1, len(versions) + 1)
    ax.bar(x, [v.rms_deg for v in versions], color="#e8590c", width=0.6)
    ax.set_xticks(x, [f"v{v.number}\n{v.change}" for v in versions], fontsize=8)
    ax.set(title="the error falling", ylabel="RMS error (°)")
    twin = ax.twinx()
    twin.plot(x, [v.fit_percent_increment for v in versions], "o-", color="#1c7ed6")
    twin.set_ylabel("fit of increments (%)", color="#1c7ed6")


def _budget(ax: Any, versions: Sequence[ModelVersion]) -> None:  # noqa: ANN401
    """Stacked bar per version: sensor floor, the rest of the floor, what each change explained,
    what is left (mean squares, as % of version 1's), all against the newest version's floor."""
    with_b = [v for v in versions if v.budget is not None]
    if not with_b:
        ax.text(0.5, 0.5, "no error budget stored\n(versions kept without one)", ha="center", va="center")
        ax.set_axis_off()
        return
    total = with_b[0].budget_rms_deg ** 2 or 1.0
    latest = with_b[-1].budget
    assert latest is not None
    colours: dict[str, str] = dict(BUDGET_COLOURS)
    used: dict[str, Any] = {}
    for i, v in enumerate(with_b):
        assert v.budget is not None
        bottom = 0.0
        for label, ms in v.budget.rebased(latest).segments_deg2():
            if label not in colours:
                colours[label] = EFFECT_COLOURS[(len(colours) - len(BUDGET_COLOURS)) % len(EFFECT_COLOURS)]
            h = 100.0 * max(ms, 0.0) / total
            bar = ax.bar(i + 1, h, bottom=bottom, color=colours[label], width=0.6, edgecolor="white", lw=0.5)
            used.setdefault(label, bar)
            bottom += h
        b = v.budget.rebased(latest)
        ax.annotate(
            f"{b.rms_deg:.3g}° RMS\nfloor {b.floor_deg:.3g}°\nleft {b.left_deg:.3g}°",
            (i + 1, min(bottom, 100.0)),
            ha="center",
            va="top" if bottom > 60 else "bottom",
            fontsize=7,
            xytext=(0, -4 if bottom > 60 else 4),
            textcoords="offset points",
            color="white" if bottom > 60 else "#212529",
        )
    ax.set_xticks(np.arange(1, len(with_b) + 1), [f"v{v.number}" for v in with_b])
    last = with_b[-1].budget
    assert last is not None
    done = (
        "at the floor: done for this run" if last.at_floor else f"{last.left_deg:.3g}° left above the floor"
    )
    ax.set(title=f"error budget (latest: {done})", ylabel="% of v1's squared error")
    ax.legend(used.values(), used.keys(), fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))


def plot_workbench(
    path: str | Path,
    compared: CompareResult | None = None,
    versions: Sequence[ModelVersion] = (),
    title: str = "",
) -> Path:
    """Write the pictures of ``compared`` (a comparison, its residual test) and ``versions``
    (the history: error falling, error budget) to ``path`` (PNG); returns the path."""
    out = Path(path)
    if out.suffix.lower() != ".png":
        raise ConfigError(f"--plot {path}: give a .png file name")
    if not out.parent.exists():
        raise ConfigError(f"--plot {path}: folder {out.parent} does not exist")
    plt = _pyplot()
    rows = (2 if compared is not None else 0) + (1 if versions else 0)
    fig, axes = plt.subplots(rows, 2, figsize=(13, 3.6 * rows), squeeze=False)
    row = 0
    if compared is not None:
        _overlay(axes[0][0], compared)
        _residual(axes[0][1], compared)
        _autocorr(axes[1][0], compared)
        _regimes(axes[1][1], compared)
        row = 2
    if versions:
        _versions(axes[row][0], versions)
        _budget(axes[row][1], versions)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


__all__ = ["plot_workbench"]
