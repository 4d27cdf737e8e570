"""Least squares of a camera model's parameters on the k-step prediction error of a log.

Starting values come from the data: for a fixed latency the angle is linear in the speeds (no
acceleration limit, no play), so the speed map is a linear least-squares problem; latency and
acceleration are searched on a grid with it (latency 0 … 1 s by quarter command periods,
acceleration log-spaced), the backlash width on a grid of the full simulation. Then
``scipy.optimize.least_squares`` refits every free parameter within its bounds.

The table carries a weak prior (``SMOOTHNESS``): each step's log-speed is pulled toward the
line through its neighbours', so a step the log holds for a row or two follows them instead of
its few errors (a 10 % kink costs about half a quantization floor per step; a step held for
a dozen rows follows its data). Steps of the speed table the log never commands (within the
scored windows) in a
direction are not fitted: they are interpolated from their neighbours (geometric, the shape of
every table we know) and listed in ``unobserved_steps``. Standard errors are the Gauss–Newton
covariance times the horizon in rows (the k-step errors of overlapping windows are correlated
over k rows, so the residuals carry about 1/k as much independent information).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from tracker.errors import DataError
from tracker.workbench.camera.log import CameraLog
from tracker.workbench.camera.model import BOUNDS, CameraModel, param_bounds
from tracker.workbench.camera.predict import count_step_rad, fit_percent, horizon_rows
from tracker.workbench.camera.simulate import simulate_angles

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
MIN_ROWS_PER_STEP = 1
# The table prior's weight, in quantization floors per unit of log-speed off the neighbours' line
SMOOTHNESS = 5.0
ACCEL_GRID_RAD_S2 = np.append(np.geomspace(0.05, 300.0, 16), np.inf)
BACKLASH_GRID_RAD = np.radians([0.0, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.6, 0.8, 1.0, 1.5, 2.0, 3.0])


@dataclass(frozen=True, slots=True)
class CameraFitResult:
    """The refitted model and its figures."""

    model: CameraModel
    fit_percent_increment: float
    rms_deg: float
    stderr: dict[str, float]
    fitted: tuple[str, ...]
    unobserved_steps: dict[str, tuple[int, ...]]
    horizon_rows: int

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": "camera",
            "fit_percent_increment": self.fit_percent_increment,
            "rms_deg": self.rms_deg,
            "params": self.model.params(),
            "stderr": self.stderr,
            "fitted": list(self.fitted),
            "unobserved_steps": {k: list(v) for k, v in self.unobserved_steps.items()},
            "effects": list(self.model.effects),
            "horizon_rows": self.horizon_rows,
        }


class _Problem:
    """The free parameters as a vector, and the k-step errors they give (fast: no model objects).

    The vector ``z`` is unconstrained for Levenberg–Marquardt: speeds as logarithms (positive),
    the acceleration limit as its reciprocal (0 = no limit), latency and backlash as themselves;
    the non-negative ones through |z|, each clipped to its upper bound.
    """

    def __init__(
        self, log: CameraLog, model: CameraModel, k: int, rows: BoolArray, free: tuple[str, ...]
    ) -> None:
        self.log, self.model, self.k, self.rows, self.free = log, model, k, rows, free
        self.inc = (log.theta_rad[k:] - log.theta_rad[:-k])[rows]
        step = log.step
        self.sign = np.sign(step).astype(float)
        self.index = np.clip(np.abs(step), 1, model.n_steps) - 1  # table entry of each row
        self.table = model.has("speed_table")
        self.pos0 = np.array(model.table_positive_rad_s, dtype=float)
        self.neg0 = np.array(model.table_negative_rad_s, dtype=float)
        self.slots: list[tuple[str, int]] = []  # (what, table index) per entry of z
        self.smooth_weight = 0.0
        self.triples: list[tuple[str, int, int, int]] = []  # consecutive free steps per direction
        for direction in ("positive", "negative"):
            ks = sorted(
                int(n.rsplit(".", 1)[1]) - 1 for n in free if n.startswith(f"speed_table.{direction}.")
            )
            self.triples += [(direction, a, b, c) for a, b, c in zip(ks, ks[1:], ks[2:], strict=False)]
        for n in free:
            if n.startswith("speed_table."):
                _, direction, k_text = n.split(".")
                self.slots.append((direction, int(k_text) - 1))
            else:
                self.slots.append((n, -1))

    def unpack(self, z: FloatArray) -> dict[str, float]:
        """Parameter values (model units) of the vector ``z``."""
        out: dict[str, float] = {}
        for n, v in zip(self.free, z, strict=True):
            out[n] = self._value(n, float(v))
        return out

    @staticmethod
    def _value(name: str, v: float) -> float:
        if name.startswith("speed"):
            lo, hi = param_bounds(name)
            return min(max(math.exp(min(v, 50.0)), lo), hi)
        # |z|: non-negative with a gradient on both sides of 0 (a clip would be flat below it)
        if name == "acceleration.limit":
            r = min(abs(v), 1.0 / BOUNDS["acceleration.limit"][0])
            return 1.0 / r if r > 0 else math.inf
        lo, hi = param_bounds(name)
        return min(max(abs(v), lo), hi)

    def pack(self, values: dict[str, float]) -> FloatArray:
        """The vector of parameter values."""
        z = []
        for n in self.free:
            v = values[n]
            if n.startswith("speed"):
                z.append(math.log(max(v, 1e-9)))
            elif n == "acceleration.limit":
                z.append(1.0 / v if math.isfinite(v) and v > 0 else 0.0)
            else:
                z.append(v)
        return np.array(z, dtype=float)

    def parts(self, values: dict[str, float]) -> tuple[FloatArray, float, float, float]:
        m = self.model
        if self.table:
            pos, neg = self.pos0.copy(), self.neg0.copy()
            for n, v in values.items():
                if n.startswith("speed_table.positive."):
                    pos[int(n.rsplit(".", 1)[1]) - 1] = v
                elif n.startswith("speed_table.negative."):
                    neg[int(n.rsplit(".", 1)[1]) - 1] = v
            speeds = np.where(self.sign > 0, pos[self.index], -neg[self.index]) * (self.sign != 0)
        else:
            speeds = values.get("speed.per_step", m.per_step_rad_s) * self.log.step.astype(float)
        lat = values.get("latency.seconds", m.effective_latency_s)
        acc = values.get("acceleration.limit", m.effective_accel_rad_s2)
        width = values.get("backlash.width", m.effective_backlash_rad)
        return speeds, lat, acc, width

    def errors(self, values: dict[str, float]) -> FloatArray:
        speeds, lat, acc, width = self.parts(values)
        return self._errors(speeds, lat, acc, width)

    def _errors(self, speeds: FloatArray, lat: float, acc: float, width: float) -> FloatArray:
        phi = simulate_angles(self.log.t_s, speeds, latency_s=lat, accel_rad_s2=acc, backlash_rad=width)
        return self.inc - (phi[self.k :] - phi[: -self.k])[self.rows]

    def residual(self, z: FloatArray) -> FloatArray:
        """The k-step errors at ``z`` (the hot path: no dictionaries)."""
        m = self.model
        pos, neg = self.pos0.copy(), self.neg0.copy()
        per_step = m.per_step_rad_s
        lat, acc, width = m.effective_latency_s, m.effective_accel_rad_s2, m.effective_backlash_rad
        for (what, idx), n, v in zip(self.slots, self.free, z, strict=True):
            value = self._value(n, float(v))
            if what == "positive":
                pos[idx] = value
            elif what == "negative":
                neg[idx] = value
            elif what == "speed.per_step":
                per_step = value
            elif what == "latency.seconds":
                lat = value
            elif what == "acceleration.limit":
                acc = value
            elif what == "backlash.width":
                width = value
        if self.table:
            speeds = np.where(self.sign > 0, pos[self.index], -neg[self.index]) * (self.sign != 0)
        else:
            speeds = per_step * self.log.step.astype(float)
        err = self._errors(speeds, lat, acc, width)
        if self.triples and self.smooth_weight > 0:
            return np.concatenate((err, self.smoothness(pos, neg)))
        return err

    def smoothness(self, pos: FloatArray, neg: FloatArray) -> FloatArray:
        """The table's prior: a weak pull of each log-speed toward the line through its free
        neighbours (a step seen in a row or two follows them; one seen often follows its data)."""
        out = np.empty(len(self.triples))
        for i, (direction, a, b, c) in enumerate(self.triples):
            t = pos if direction == "positive" else neg
            la, lb, lc = math.log(t[a]), math.log(t[b]), math.log(t[c])
            w = (b - a) / (c - a)
            out[i] = self.smooth_weight * (lb - (la + w * (lc - la)))
        return out


def observed_steps(log: CameraLog, rows: BoolArray | None, k: int, n_steps: int) -> dict[str, set[int]]:
    """Steps commanded for at least MIN_ROWS_PER_STEP rows, per direction, within the rows whose
    predictions are scored (a command counts when it lies in a scored window)."""
    if rows is None:
        near = np.ones(log.n, dtype=bool)
    else:
        scored = np.zeros(log.n, dtype=bool)
        scored[k:] = rows
        # rows j whose command is held inside some scored window: rows i in j+1..j+k
        c = np.concatenate(([0], np.cumsum(scored.astype(np.int64))))  # c[i] = scored rows before i
        j = np.arange(log.n)
        near = (c[np.minimum(j + k + 1, log.n)] - c[np.minimum(j + 1, log.n)]) > 0
    out: dict[str, set[int]] = {}
    for name, sel in (("positive", log.step > 0), ("negative", log.step < 0)):
        steps, counts = np.unique(np.abs(log.step[sel & near]), return_counts=True)
        out[name] = {
            int(s) for s, c in zip(steps, counts, strict=True) if c >= MIN_ROWS_PER_STEP and s <= n_steps
        }
    return out


def _speed_columns(p: _Problem, names: list[str], latency_s: float) -> FloatArray:
    """The k-step increment each speed parameter moves per rad/s (the model is linear in them
    at a fixed latency without acceleration limit or play). Shape (scored rows, len(names))."""
    cols = []
    for name in names:
        if name == "speed.per_step":
            speeds = p.log.step.astype(float)
        else:
            direction, k_text = name.split(".")[1:]
            sel = (p.index == int(k_text) - 1) & (p.sign == (1.0 if direction == "positive" else -1.0))
            speeds = np.where(sel, p.sign, 0.0)
        phi = simulate_angles(p.log.t_s, speeds, latency_s=latency_s)
        cols.append((phi[p.k :] - phi[: -p.k])[p.rows])
    return np.column_stack(cols)


def _linear_speeds(p: _Problem, names: list[str], latency_s: float) -> tuple[FloatArray, float]:
    if not names:
        return np.zeros(0), float(np.sum(p.errors({"latency.seconds": latency_s}) ** 2))
    a = _speed_columns(p, names, latency_s)
    fixed = p.errors(
        {
            "latency.seconds": latency_s,
            "acceleration.limit": math.inf,
            "backlash.width": 0.0,
            **{n: 0.0 for n in names},
        }
    )
    # normal equations (a few dozen columns): lstsq's SVD costs 100x more here
    # (einsum, not BLAS: threaded BLAS thrashes on these small products on a busy machine)
    ata = np.einsum("ij,ik->jk", a, a)
    atb = np.einsum("ij,i->j", a, fixed)
    sol = np.linalg.solve(ata + 1e-12 * np.trace(ata) * np.eye(ata.shape[0]), atb)
    cost = float(np.sum((fixed - a @ sol) ** 2))
    # a speed the linear problem makes non-positive (the effects it ignores distort it) starts
    # on the map of the others instead: the fit works on log-speeds and cannot leave zero
    steps = np.array([1.0 if n == "speed.per_step" else float(n.rsplit(".", 1)[1]) for n in names])
    good = sol > 0
    per_step = float(np.median(sol[good] / steps[good])) if good.any() else math.radians(1.0)
    sol = np.where(good & (sol > 0.2 * per_step * steps), sol, per_step * steps)
    lo, hi = param_bounds(names[0])
    return np.clip(sol, lo, hi), cost


def _interpolated_table(table: FloatArray, known: set[int]) -> FloatArray:
    """``table`` with the steps not in ``known`` interpolated geometrically from the known ones."""
    if not known:
        return table
    ks = np.array(sorted(known))
    steps = np.arange(1, table.size + 1)
    return np.asarray(np.exp(np.interp(steps, ks, np.log(np.maximum(table[ks - 1], 1e-9)))), dtype=float)


def _fill_tables(model: CameraModel, obs: dict[str, set[int]]) -> CameraModel:
    """Unobserved table steps follow their neighbours; a direction never driven copies the other."""
    if not model.has("speed_table"):
        return model
    pos = _interpolated_table(np.array(model.table_positive_rad_s), obs["positive"])
    neg = _interpolated_table(np.array(model.table_negative_rad_s), obs["negative"])
    if not obs["positive"]:
        pos = neg.copy()
    if not obs["negative"]:
        neg = pos.copy()
    values = {f"speed_table.positive.{i + 1}": float(v) for i, v in enumerate(pos)}
    values |= {f"speed_table.negative.{i + 1}": float(v) for i, v in enumerate(neg)}
    return model.with_params(values)


def free_parameters(
    model: CameraModel, obs: dict[str, set[int]], free: tuple[str, ...] | None
) -> tuple[str, ...]:
    """The parameters to fit: ``free`` if given, else every one but the quantization step and
    the table steps the log does not command."""
    names = []
    for name in model.params():
        if name == "quantization.step":
            continue
        if name.startswith("speed_table."):
            _, direction, k_text = name.split(".")
            if int(k_text) not in obs[direction]:
                continue
        names.append(name)
    if free is None:
        return tuple(names)
    unknown = [f for f in free if f not in model.params()]
    if unknown:
        raise DataError(
            f"cannot fit {', '.join(unknown)}: not a parameter of this model ({', '.join(model.params())})"
        )
    return tuple(f for f in free if f in names or not f.startswith("speed_table."))


def _start(p: _Problem, names: tuple[str, ...]) -> dict[str, float]:
    """Starting values from the data (see the module docstring)."""
    m = p.model
    speed_names = [n for n in names if n.startswith(("speed.", "speed_table."))]
    period = p.log.period_s
    lat_grid = (
        np.arange(0.0, min(1.0, 25 * period) + 1e-9, period / 4)
        if "latency.seconds" in names
        else np.array([m.effective_latency_s])
    )
    acc_grid = ACCEL_GRID_RAD_S2 if "acceleration.limit" in names else np.array([m.effective_accel_rad_s2])
    lin = [(lat, *_linear_speeds(p, speed_names, float(lat))) for lat in lat_grid]
    best: tuple[float, dict[str, float]] | None = None
    for lat, sol, _ in lin:
        for acc in acc_grid:
            values = {n: float(v) for n, v in zip(speed_names, sol, strict=True)}
            values |= {"latency.seconds": float(lat), "acceleration.limit": float(acc)}
            cost = float(np.sum(p.errors(values) ** 2))
            if best is None or cost < best[0]:
                best = (cost, values)
    assert best is not None
    values = best[1]
    if "backlash.width" in names:
        costs = [
            float(np.sum(p.errors({**values, "backlash.width": float(w)}) ** 2)) for w in BACKLASH_GRID_RAD
        ]
        # not exactly 0: the play's cost is flat in width until the width matters
        values["backlash.width"] = max(float(BACKLASH_GRID_RAD[int(np.argmin(costs))]), BACKLASH_GRID_RAD[1])
    out = {n: values.get(n, m.params().get(n, 0.0)) for n in names}
    for n in names:
        lo, hi = param_bounds(n)
        out[n] = min(max(out[n], lo), hi)
    return out


def fit_camera(
    log: CameraLog,
    model: CameraModel,
    *,
    horizon_s: float | None = None,
    rows: BoolArray | None = None,
    free: tuple[str, ...] | None = None,
    start: bool = True,
) -> CameraFitResult:
    """Refit ``model`` on ``log``: starting values from the data (``start``), then nonlinear
    least squares on the k-step errors of the predictions in ``rows`` (a mask over rows k..n-1;
    all by default). With the quantization effect, its step is the count found in the data."""
    k = horizon_rows(log, horizon_s)
    mask = np.ones(log.n - k, dtype=bool) if rows is None else np.asarray(rows, dtype=bool)
    if mask.shape != (log.n - k,):
        raise DataError(f"rows mask has shape {mask.shape}, the log has {log.n - k} predictions")
    if model.has("quantization"):
        model = model.with_params({"quantization.step": min(count_step_rad(log), 0.1)})
    obs = observed_steps(log, mask, k, model.n_steps)
    names = free_parameters(model, obs, free)
    p = _Problem(log, model, k, mask, names)
    q = count_step_rad(log)
    p.smooth_weight = SMOOTHNESS * max(q / math.sqrt(6.0), 1e-4)
    first = _start(p, names) if start and names else model.params()
    stderr: dict[str, float] = {}
    if names:
        z0 = p.pack(first)
        # Levenberg–Marquardt (MINPACK: no threaded BLAS, a few dozen iterations); bounds by
        # the transforms of _Problem
        sol = least_squares(
            p.residual,
            z0,
            method="lm",
            diff_step=1e-6,
            xtol=1e-12,
            ftol=1e-12,
            max_nfev=40 * (len(names) + 1),
        )
        z = sol.x
        dof = max(1, int(mask.sum()) - len(names))
        s2 = float(np.sum(sol.fun**2)) / dof
        cov = np.linalg.pinv(np.einsum("ij,ik->jk", sol.jac, sol.jac)) * s2 * k
        fitted = p.unpack(z)
        for i, n in enumerate(names):  # back to the model's units: dv = dz * dv/dz
            sz = math.sqrt(max(cov[i, i], 0.0))
            if n.startswith("speed"):
                stderr[n] = fitted[n] * sz
            elif n == "acceleration.limit":
                stderr[n] = sz * fitted[n] ** 2 if math.isfinite(fitted[n]) else math.inf
            else:
                stderr[n] = sz
        model = model.with_params(fitted)
    model = _fill_tables(model, obs)
    err = _Problem(log, model, k, mask, ()).residual(np.zeros(0))
    inc = p.inc
    return CameraFitResult(
        model=model,
        fit_percent_increment=fit_percent(err, inc),
        rms_deg=math.degrees(float(np.sqrt(np.mean(err**2)))) if err.size else 0.0,
        stderr=stderr,
        fitted=names,
        unobserved_steps={
            d: tuple(s for s in range(1, model.n_steps + 1) if s not in obs[d])
            for d in ("positive", "negative")
        }
        if model.has("speed_table")
        else {},
        horizon_rows=k,
    )


def _scale_floor(name: str, log: CameraLog) -> float:
    if name == "latency.seconds":
        return log.period_s
    if name == "acceleration.limit":
        return 1e-3  # s²/rad, of the reciprocal
    if name == "backlash.width":
        return math.radians(0.1)
    return 1e-3
