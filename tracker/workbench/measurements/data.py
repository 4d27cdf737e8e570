"""Measurement logs: the one CSV format (``t`` s, ``u`` V, ``theta`` rad) read and written everywhere.

A log has a header row; columns ``t``, ``u`` and ``theta`` are required, other columns are
allowed and ignored. Time must increase with an even sample interval. Every problem is a
:class:`DataError` naming the line (1-based, the header is line 1) or the column.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tracker.errors import DataError

FloatArray = NDArray[np.float64]
REQUIRED_COLUMNS = ("t", "u", "theta")
MIN_SAMPLES = 200
# Sample intervals may jitter by this fraction of the median before the log is called uneven.
SAMPLING_TOLERANCE = 0.05


@dataclass(frozen=True, slots=True)
class Measurement:
    """A measured (or simulated) run of one axis. Arrays have shape (n,)."""

    t_s: FloatArray
    u_v: FloatArray
    theta_rad: FloatArray
    source: str = ""
    _dt_s: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # The fitter asks for dt at every model evaluation: take the median once.
        dt = float(np.median(np.diff(self.t_s))) if np.size(self.t_s) > 1 else math.nan
        object.__setattr__(self, "_dt_s", dt)

    @property
    def dt_s(self) -> float:
        """The sample interval (median of the differences)."""
        return self._dt_s

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t_s.size)

    def slice(self, start: int, stop: int) -> Measurement:
        """Samples ``start:stop`` as a new measurement."""
        return Measurement(
            self.t_s[start:stop], self.u_v[start:stop], self.theta_rad[start:stop], self.source
        )


def parse_number(text: str, where: str, column: str) -> float:
    """A finite float from a CSV field; DataError naming where and the column otherwise."""
    try:
        value = float(text)
    except ValueError:
        raise DataError(f"{where}: {column} is {text.strip()!r}, not a number") from None
    if not math.isfinite(value):
        raise DataError(f"{where}: {column} is {text.strip()!r}")
    return value


def _read_rows(reader: Iterator[list[str]], source: str) -> list[tuple[float, float, float]]:
    """The (t, u, theta) rows of a log; raises DataError naming the line or column."""
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise DataError(f"{source}: empty file, expected a header row with t,u,theta") from None
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise DataError(
            f"{source}: line 1: missing column {', '.join(missing)} (header has: {', '.join(header)})"
        )
    idx = [header.index(c) for c in REQUIRED_COLUMNS]
    rows: list[tuple[float, float, float]] = []
    for line_no, row in enumerate(reader, start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) < len(header):
            raise DataError(f"{source}: line {line_no}: {len(row)} fields, header has {len(header)}")
        t, u, th = (
            parse_number(row[i], f"{source}: line {line_no}", c)
            for i, c in zip(idx, REQUIRED_COLUMNS, strict=True)
        )
        rows.append((t, u, th))
    return rows


def parse_log(text: str, source: str = "<data>") -> Measurement:
    """Parse CSV text in the log format; raise DataError naming the line or column."""
    reader = csv.reader(io.StringIO(text))
    try:
        rows = _read_rows(reader, source)
    except csv.Error as exc:  # e.g. a stray carriage return inside a field
        raise DataError(f"{source}: line {reader.line_num}: not valid CSV ({exc})") from None
    if not rows:
        raise DataError(f"{source}: no data rows after the header")
    arr = np.asarray(rows, dtype=float)
    return validate(Measurement(arr[:, 0], arr[:, 1], arr[:, 2], source))


def validate(m: Measurement) -> Measurement:
    """Check time increases evenly and there are enough samples; return ``m`` unchanged."""
    src = m.source or "<data>"
    if m.n < MIN_SAMPLES:
        raise DataError(f"{src}: only {m.n} samples; at least {MIN_SAMPLES} are needed to say anything")
    for name, arr in (("t", m.t_s), ("u", m.u_v), ("theta", m.theta_rad)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise DataError(f"{src}: line {bad[0] + 2}: {name} is {arr[bad[0]]!r}")
    check_clock(m.t_s, src, SAMPLING_TOLERANCE, "sampling")
    return m


def read_log(path: str | Path) -> Measurement:
    """Read a measurement log from ``path``."""
    return parse_log(read_text(path), str(path))


def read_text(path: str | Path) -> str:
    """A log file's text; DataError saying why it cannot be read."""
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DataError(f"{p}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{p}: cannot read ({exc})") from None


def check_clock(t_s: FloatArray, src: str, tolerance: float, period: str) -> None:
    """Time must increase, evenly within ``tolerance`` of the median step (``period`` names the
    step in the message: "sampling", "command period"); DataError naming the line otherwise."""
    dt = np.diff(t_s)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        k = int(bad[0])
        raise DataError(
            f"{src}: line {k + 3}: time does not increase (t = {t_s[k + 1]:g} after {t_s[k]:g})"
        )
    med = float(np.median(dt))
    uneven = np.flatnonzero(np.abs(dt - med) > tolerance * med)
    if uneven.size:
        k = int(uneven[0])
        raise DataError(
            f"{src}: line {k + 3}: uneven {period} (step {dt[k]:g} s, the log's step is {med:g} s)"
        )


def format_log(m: Measurement, extra: dict[str, FloatArray] | None = None) -> str:
    """The log as CSV text; ``extra`` adds columns (ignored by readers)."""
    cols = {"t": m.t_s, "u": m.u_v, "theta": m.theta_rad, **(extra or {})}
    out = io.StringIO()
    out.write(",".join(cols) + "\n")
    data = np.column_stack([np.asarray(v, dtype=float) for v in cols.values()])
    np.savetxt(out, data, delimiter=",", fmt="%.10g")
    return out.getvalue()


def write_log(path: str | Path, m: Measurement, extra: dict[str, FloatArray] | None = None) -> None:
    """Write ``m`` to ``path`` atomically (a partial file never replaces a good one)."""
    p = Path(path)
    tmp = p.with_name(p.name + ".part")
    tmp.write_text(format_log(m, extra), encoding="utf-8")
    tmp.replace(p)
