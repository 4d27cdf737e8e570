"""``tracker model``'s versions: where a fit is kept (a workspace folder, or the console's database
with ``--db``), ``tracker model history`` (the error falling, the error budget) and ``--plot``.

A workspace keeps one JSON history per log (named by its stem and a hash of its bytes); the
console's database keeps the versions of each measurement (found by its data), the same records
the browser shows, so a fit from the command line appears in the console and the other way round.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from tracker.errors import ConfigError
from tracker.plant.model import AxisModel
from tracker.workbench.budget import ErrorBudget, error_budget
from tracker.workbench.compare.compare import CompareResult, compare_model
from tracker.workbench.fit.fit import FitResult
from tracker.workbench.measurements.data import Measurement, parse_log, read_log
from tracker.workbench.versions import ModelVersion, VersionHistory

DEFAULT_WORKSPACE = ".tracker-workspace"


def history_name(path: str) -> str:
    """The name a log's versions are kept under in a workspace: its file stem and a hash of its bytes."""
    data = Path(path).read_bytes()
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(path).stem)[:48] or "log"
    return f"{stem}-{hashlib.sha1(data).hexdigest()[:8]}"


class Keeper(Protocol):
    """Where the versions of one log live."""

    @property
    def where(self) -> str: ...

    def load(self) -> VersionHistory: ...

    def append(self, version: ModelVersion, extra: dict[str, Any]) -> str: ...


@dataclass
class FolderKeeper:
    """A workspace folder (one JSON file per log)."""

    folder: str
    name: str

    @property
    def where(self) -> str:
        return f"{self.name} in {self.folder}"

    def load(self) -> VersionHistory:
        from tracker.workbench.versions import VersionStore

        return VersionStore(self.folder).load(self.name)

    def append(self, version: ModelVersion, extra: dict[str, Any]) -> str:
        from tracker.workbench.versions import VersionStore

        store = VersionStore(self.folder)
        store.save(self.name, store.load(self.name).appended(version))
        return f"kept as version {version.number} ({version.change}) of {self.where}"


@dataclass
class DatabaseKeeper:
    """The console's database: the measurement with this log's data (added when new)."""

    db_path: str
    meas: Measurement
    text: str
    label: str
    axis: str

    @property
    def where(self) -> str:
        return f"the console's database {self.db_path}"

    def load(self) -> VersionHistory:
        from tracker.workbench.version_db import ConsoleDatabase

        with ConsoleDatabase(self.db_path) as db:
            found = db.find(self.meas)
            return VersionHistory() if found is None else db.history(found.id)[0]

    def append(self, version: ModelVersion, extra: dict[str, Any]) -> str:
        from tracker.workbench.version_db import ConsoleDatabase

        with ConsoleDatabase(self.db_path) as db:
            found = db.find(self.meas)
            axis = found.axis if found is not None else self.axis
            rec, vid = db.append(self.meas, self.text, self.label, axis, version, extra)
        return (
            f"kept as version {version.number} ({version.change}) of measurement #{rec.id} "
            f"({rec.name}) in {self.db_path} (version id {vid}; the console shows it)"
        )


def keeper_for(args: argparse.Namespace, meas: Measurement, axis: str) -> Keeper:
    """``--db PATH``: the console's database; else the ``--workspace`` folder."""
    if getattr(args, "db", None):
        text = Path(args.data).read_text(encoding="utf-8-sig")
        return DatabaseKeeper(args.db, meas, text, Path(args.data).name[:120], axis)
    return FolderKeeper(args.workspace, history_name(args.data))


def change_from(history: VersionHistory, model: AxisModel) -> str:
    """What made a new version with ``model``: ``base``, ``+gravity``, ``-ripple``, ``refit``."""
    if not history.versions:
        return "base" + "".join(f"+{e}" for e in model.effects)
    before = set(history.latest.model.effects)
    change = "".join(f"+{e}" for e in model.effects if e not in before)
    change += "".join(f"-{e}" for e in history.latest.model.effects if e not in set(model.effects))
    return change or "refit"


def budget_for(
    meas: Measurement, history: VersionHistory, model: AxisModel, change: str, compared: CompareResult | None
) -> ErrorBudget | None:
    """The error budget of a new version after ``history``."""
    earlier = [(v.change, v.budget_rms_deg) for v in history.versions]
    return error_budget(meas, model, earlier, change, compared=compared)


def record_version(
    args: argparse.Namespace,
    meas: Measurement,
    res: FitResult,
    compared: CompareResult | None,
    extra: dict[str, Any],
) -> list[str]:
    """Keep ``res`` as the next version of the log's history, with its error budget (when
    ``compared`` has a residual test); the lines to print."""
    keeper = keeper_for(args, meas, args.axis)
    hist = keeper.load()
    change = change_from(hist, res.model)
    budget = budget_for(meas, hist, res.model, change, compared) if compared is not None else None
    number = hist.latest.number + 1 if hist.versions else 1
    version = ModelVersion.from_fit(number, change, res, meas.source, budget)
    lines = [keeper.append(version, extra)]
    if budget is not None:
        lines += ["error budget of this version (RMS, deg):", *budget.describe()]
    return lines


def format_history(meas: Measurement, versions: list[ModelVersion], where: str) -> str:
    """The error falling version by version, and the error budget of the latest version."""
    latest = versions[-1].budget if versions else None
    lines = [
        f"{meas.source}: {len(versions)} version(s) in {where}",
        f"{'v':>3} {'change':<24} {'RMS deg':>11} {'fit %':>9} {'incr. fit %':>11}  "
        "left above the floor, deg",
    ]
    for v in versions:
        b = v.budget.rebased(latest) if v.budget is not None and latest is not None else None
        tail = f"{b.left_deg:.4g}{'  (at the floor)' if b.left_deg <= 0 or b.consistent else ''}" if b else ""
        lines.append(
            f"{v.number:>3} {v.change:<24} {v.rms_deg:11.4g} {v.fit_percent:9.3f} "
            f"{v.fit_percent_increment:11.2f}  {tail}"
        )
    last = versions[-1].budget if versions else None
    if last is not None:
        lines += [
            "",
            f"error budget of the latest version, v{versions[-1].number} (RMS, deg):",
            *last.describe(),
        ]
    return "\n".join(lines)


def _history_source(args: argparse.Namespace) -> tuple[Measurement, Keeper | None, VersionHistory, str]:
    """The log, its keeper and its versions (``--measurement ID`` reads the log from ``--db``)."""
    if args.measurement is not None:
        if not args.db:
            raise ConfigError("--measurement needs --db (the console's database the measurement is in)")
        from tracker.workbench.version_db import ConsoleDatabase

        with ConsoleDatabase(args.db) as db:
            text = db.measurement_text(args.measurement)
            hist, _ = db.history(args.measurement)
        meas = parse_log(text, f"measurement #{args.measurement}")
        return meas, None, hist, f"the console's database {args.db}"
    if not args.data:
        raise ConfigError("give DATA.csv (or --db PATH --measurement ID)")
    meas = read_log(args.data)
    keeper = keeper_for(args, meas, "pan")
    return meas, keeper, keeper.load(), keeper.where


def run_history(args: argparse.Namespace) -> int:
    """``tracker model history``."""
    from tracker.cli.model import _json

    meas, _, hist, where = _history_source(args)
    if not hist.versions:
        hint = (
            f"`tracker model fit {args.data} --axis pan|tilt --db {args.db}`"
            if args.db
            else f"`tracker model fit {args.data} --axis pan|tilt --workspace {args.workspace}`"
        )
        raise ConfigError(f"{args.data or meas.source}: no versions in {where}; make one with {hint}")
    vs = list(hist.versions)
    compared = None
    if args.plot or (vs[-1].budget is None and args.replicas > 0):
        compared = compare_model(meas, vs[-1].model, replicas=args.replicas)
    if vs[-1].budget is None and compared is not None and compared.verdict is not None:
        # an older version kept without one: its budget now (not stored: history only reads)
        earlier = VersionHistory(tuple(vs[:-1]))
        b = budget_for(meas, earlier, vs[-1].model, vs[-1].change, compared)
        vs[-1] = dataclasses.replace(vs[-1], budget=b)
    if args.json:
        print(_json({"source": where, "versions": [v.to_dict() for v in vs]}))
    else:
        print(format_history(meas, vs, where))
    if args.plot:
        write_plot(
            args.plot, compared, vs, f"{meas.source}: v{vs[-1].number} ({vs[-1].change}) and its history"
        )
    return 0


def write_plot(path: str, compared: CompareResult | None, versions: list[ModelVersion], title: str) -> None:
    """``--plot FILE.png``: the console's pictures (import matplotlib only now)."""
    from tracker.workbench.plots import plot_workbench

    out = plot_workbench(path, compared, versions, title)
    print(f"wrote {out}")


def add_store_options(p: argparse.ArgumentParser) -> None:
    """``--workspace`` / ``--db`` (where versions are kept) and ``--plot``."""
    p.add_argument("--workspace", default=DEFAULT_WORKSPACE, metavar="DIR", help="where versions are kept")
    p.add_argument(
        "--db",
        default=None,
        metavar="PATH",
        help="keep versions in the console's database (data_dir/console.sqlite3): the browser shows them",
    )
    add_plot_option(p)


def add_plot_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plot", default=None, metavar="FILE.png", help="write the console's pictures to a PNG")


def versions_in(args: argparse.Namespace, meas: Measurement) -> list[ModelVersion]:
    """The versions kept for the log (for ``fit --plot``), newest last."""
    return list(keeper_for(args, meas, args.axis).load().versions)


__all__ = [
    "DEFAULT_WORKSPACE",
    "DatabaseKeeper",
    "FolderKeeper",
    "add_store_options",
    "format_history",
    "history_name",
    "record_version",
    "run_history",
    "write_plot",
]
