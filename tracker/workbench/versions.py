"""Model versions: every change to a model's structure is a new, refitted version with its fit kept.

Adding an effect makes version n+1: the structure grows by one effect and *every* free
parameter is refitted (the old values are only the start), so the history shows the error
falling step by step. A :class:`VersionHistory` is an immutable list of versions; a
:class:`VersionStore` keeps one history per name as JSON files in a folder (written atomically:
a crash never leaves half a file); :mod:`~tracker.workbench.version_db` keeps the same versions
in the console's database, so the console and the command line share them.
"""

from __future__ import annotations

import json
import math
import os
import re
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from types import MappingProxyType

from tracker.errors import ConfigError, DataError
from tracker.plant.model import AxisModel
from tracker.workbench.budget import ErrorBudget
from tracker.workbench.fit.fit import FitResult, fit_model
from tracker.workbench.measurements.data import Measurement

_NAME = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


@dataclass(frozen=True, slots=True)
class ModelVersion:
    """One version of a model and how well it fits the data it was fitted on.

    ``number`` counts from 1; ``change`` says what made it (``"base"``, ``"+offset"``,
    ``"-ripple"``, ``"refit"``). ``stderr`` is keyed like ``model.params``.
    """

    number: int
    model: AxisModel
    change: str
    fit_percent: float
    fit_percent_increment: float
    rms_deg: float
    stderr: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    data_source: str = ""
    horizon_s: float = 0.0
    created_utc: str = ""
    budget: ErrorBudget | None = None

    @classmethod
    def from_fit(
        cls, number: int, change: str, fit: FitResult, data_source: str, budget: ErrorBudget | None = None
    ) -> ModelVersion:
        """A version made from a fit result (and its error budget, when computed)."""
        return cls(
            number=number,
            model=fit.model,
            change=change,
            fit_percent=fit.fit_percent,
            fit_percent_increment=fit.fit_percent_increment,
            rms_deg=fit.rms_deg,
            stderr=MappingProxyType(dict(fit.stderr)),
            data_source=data_source,
            horizon_s=fit.horizon_s,
            created_utc=datetime.now(UTC).isoformat(timespec="seconds"),
            budget=budget,
        )

    @property
    def budget_rms_deg(self) -> float:
        """The RMS the error budget splits (the residual test's samples), else ``rms_deg``."""
        return self.budget.rms_deg if self.budget is not None else self.rms_deg

    def to_dict(self) -> dict[str, object]:
        """JSON-ready."""
        return {
            "number": self.number,
            "change": self.change,
            "fit_percent": self.fit_percent,
            "fit_percent_increment": self.fit_percent_increment,
            "rms_deg": self.rms_deg,
            "model": self.model.to_dict(),
            "stderr": dict(self.stderr),
            "data_source": self.data_source,
            "horizon_s": self.horizon_s,
            "created_utc": self.created_utc,
            "budget": None if self.budget is None else self.budget.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, object], where: str) -> ModelVersion:
        """Rebuild from :meth:`to_dict` output; DataError naming ``where`` on a bad record."""
        try:
            m = d["model"]
            assert isinstance(m, Mapping)
            # Stored values go in as overrides: as base values, create() would reset an
            # asymmetry's negative side to its positive twin (a new asymmetry starts symmetric).
            model = AxisModel.create(
                float(m["gain_nm_per_v"]),
                {},
                tuple(m["effects"]),
                dict(m["params"]),
            )
            return cls(
                number=int(d["number"]),  # type: ignore[call-overload]
                model=model,
                change=str(d["change"]),
                fit_percent=_num(d["fit_percent"]),
                fit_percent_increment=_num(d.get("fit_percent_increment")),
                rms_deg=_num(d["rms_deg"]),
                stderr=MappingProxyType({str(k): float(v) for k, v in dict(d.get("stderr") or {}).items()}),  # type: ignore[call-overload]
                data_source=str(d.get("data_source", "")),
                horizon_s=_num(d.get("horizon_s")),
                created_utc=str(d.get("created_utc", "")),
                budget=ErrorBudget.from_dict(b) if isinstance(b := d.get("budget"), Mapping) else None,
            )
        except (KeyError, TypeError, ValueError, AssertionError) as exc:
            raise DataError(f"{where}: not a model version ({type(exc).__name__}: {exc})") from None


def _num(v: object) -> float:
    return math.nan if v is None else float(v)  # type: ignore[arg-type]


@dataclass(frozen=True, slots=True)
class VersionHistory:
    """An ordered, immutable list of versions (oldest first)."""

    versions: tuple[ModelVersion, ...] = ()

    @property
    def latest(self) -> ModelVersion:
        """The newest version; ConfigError when there is none."""
        if not self.versions:
            raise ConfigError("the model history is empty; fit a first version")
        return self.versions[-1]

    def get(self, number: int) -> ModelVersion:
        """Version ``number``; ConfigError listing the ones that exist."""
        for v in self.versions:
            if v.number == number:
                return v
        raise ConfigError(f"no model version {number}; versions are {[v.number for v in self.versions]}")

    def appended(self, version: ModelVersion) -> VersionHistory:
        """A new history with ``version`` at the end."""
        return VersionHistory((*self.versions, version))

    def fit_history(self) -> list[tuple[int, str, float, float]]:
        """(number, change, fit %, increment fit %) per version: the error falling."""
        return [(v.number, v.change, v.fit_percent, v.fit_percent_increment) for v in self.versions]

    def to_dict(self) -> dict[str, object]:
        """JSON-ready."""
        return {"versions": [v.to_dict() for v in self.versions]}


Progress = Callable[[float], None]
Cancel = Callable[[], bool]


def first_version(
    meas: Measurement, model: AxisModel, progress: Progress | None = None, cancel: Cancel | None = None
) -> VersionHistory:
    """Fit ``model`` to ``meas`` and start a history with it (version 1)."""
    fit = fit_model(meas, model, progress=progress, cancel=cancel)
    change = "base" if not model.effects else "base+" + "+".join(model.effects)
    return VersionHistory((ModelVersion.from_fit(1, change, fit, meas.source),))


def add_effect(
    history: VersionHistory,
    meas: Measurement,
    effect: str,
    overrides: Mapping[str, float] | None = None,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> VersionHistory:
    """A history with one more version: the latest model plus ``effect``, everything refitted."""
    latest = history.latest
    if latest.model.has(effect):
        raise ConfigError(f"version {latest.number} already has {effect!r}")
    model = latest.model.with_effect(effect, overrides)
    fit = fit_model(meas, model, progress=progress, cancel=cancel)
    return history.appended(ModelVersion.from_fit(latest.number + 1, f"+{effect}", fit, meas.source))


def remove_effect(history: VersionHistory, meas: Measurement, effect: str) -> VersionHistory:
    """A history with one more version: the latest model without ``effect``, refitted."""
    latest = history.latest
    if effect not in latest.model.effects:
        raise ConfigError(f"version {latest.number} has no {effect!r} to remove")
    fit = fit_model(meas, latest.model.without_effect(effect))
    return history.appended(ModelVersion.from_fit(latest.number + 1, f"-{effect}", fit, meas.source))


class VersionStore:
    """Histories kept as ``<folder>/<name>.json``, written atomically.

    ``folder=None`` keeps them in memory only (tests, a console session without a disk).
    """

    def __init__(self, folder: str | Path | None = None) -> None:
        self._folder = Path(folder) if folder is not None else None
        self._memory: dict[str, VersionHistory] = {}
        if self._folder is not None:
            self._folder.mkdir(parents=True, exist_ok=True)

    def _path(self, name: str) -> Path:
        if not _NAME.match(name):
            raise ConfigError(f"history name {name!r} must be 1-64 letters, digits, '_', '.', '-'")
        assert self._folder is not None
        return self._folder / f"{name}.json"

    def names(self) -> list[str]:
        """Names of the stored histories, sorted."""
        if self._folder is None:
            return sorted(self._memory)
        return sorted(p.stem for p in self._folder.glob("*.json"))

    def load(self, name: str) -> VersionHistory:
        """The history called ``name`` (empty if there is none)."""
        if self._folder is None:
            if not _NAME.match(name):
                raise ConfigError(f"history name {name!r} must be 1-64 letters, digits, '_', '.', '-'")
            return self._memory.get(name, VersionHistory())
        path = self._path(name)
        if not path.exists():
            return VersionHistory()
        try:
            raw = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise DataError(f"{path}: cannot read model versions ({exc})") from None
        items = raw.get("versions") if isinstance(raw, dict) else None
        if not isinstance(items, list):
            raise DataError(f"{path}: expected an object with a 'versions' list")
        return VersionHistory(
            tuple(ModelVersion.from_dict(v, f"{path}: version {i + 1}") for i, v in enumerate(items))
        )

    def save(self, name: str, history: VersionHistory) -> None:
        """Store ``history`` as ``name`` (replacing the old one atomically)."""
        if self._folder is None:
            self.load(name)  # validates the name
            self._memory[name] = history
            return
        path = self._path(name)
        text = json.dumps(history.to_dict(), indent=1, allow_nan=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".part", dir=self._folder)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


__all__ = ["ModelVersion", "VersionHistory", "VersionStore", "add_effect", "first_version", "remove_effect"]
