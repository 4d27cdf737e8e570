"""Camera logs: CSV ``t`` (s), ``speed_cmd`` (signed speed step), ``theta`` (rad), read and written.

The column ``speed_cmd`` (instead of the DC log's ``u``) declares the log a camera's. A row is
one command period: ``theta`` is the angle the camera reported at ``t``, ``speed_cmd`` the
Pan-tiltDrive sent at ``t`` — its step (1.. in the camera's speed table), signed by direction
(+ toward positive angles), 0 for stop — held until the next row. Every problem is a
:class:`DataError` naming the line (the header is line 1) or the column.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tracker.errors import DataError
from tracker.workbench.measurements.data import check_clock, parse_number, read_text

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
KIND_COLUMN = "speed_cmd"
REQUIRED_COLUMNS = ("t", KIND_COLUMN, "theta")
MIN_ROWS = 100
MAX_STEP = 255  # VISCA speed bytes are one byte
SAMPLING_TOLERANCE = 0.25  # a camera's command clock jitters more than a motor loop's


@dataclass(frozen=True, slots=True)
class CameraLog:
    """A logged camera run of one axis. Arrays have shape (n,)."""

    t_s: FloatArray
    step: IntArray
    theta_rad: FloatArray
    source: str = ""

    @property
    def n(self) -> int:
        """Number of rows (command periods)."""
        return int(self.t_s.size)

    @property
    def period_s(self) -> float:
        """The command period (median row interval, s)."""
        return float(np.median(np.diff(self.t_s)))

    @property
    def max_step(self) -> int:
        """The largest speed step used (either direction)."""
        return int(np.max(np.abs(self.step))) if self.n else 0


def header_of(text: str) -> list[str]:
    """The first row's column names."""
    first = text.lstrip("\ufeff").split("\n", 1)[0]
    return [h.strip() for h in first.split(",")]


def is_camera_log(text: str) -> bool:
    """True when the CSV header declares a camera log (a ``speed_cmd`` column)."""
    return KIND_COLUMN in header_of(text)


def is_camera_log_file(path: str | Path) -> bool:
    """True when the file's header declares a camera log (False if it cannot be read: the
    DC reader then reports the problem)."""
    try:
        with Path(path).open(encoding="utf-8") as fh:
            return KIND_COLUMN in header_of(fh.readline())
    except (OSError, UnicodeDecodeError):
        return False


def parse_camera_log(text: str, source: str = "<data>") -> CameraLog:
    """Parse CSV text in the camera log format; DataError naming the line or column."""
    reader = csv.reader(io.StringIO(text.lstrip("\ufeff")))
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise DataError(f"{source}: empty file, expected a header row with t,speed_cmd,theta") from None
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise DataError(
            f"{source}: line 1: missing column {', '.join(missing)} (header has: {', '.join(header)})"
        )
    idx = [header.index(c) for c in REQUIRED_COLUMNS]
    rows: list[tuple[float, float, float]] = []
    try:
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) < len(header):
                raise DataError(f"{source}: line {line_no}: {len(row)} fields, header has {len(header)}")
            where = f"{source}: line {line_no}"
            t, s, th = (parse_number(row[i], where, c) for i, c in zip(idx, REQUIRED_COLUMNS, strict=True))
            if s != round(s) or abs(s) > MAX_STEP:
                raise DataError(
                    f"{where}: speed_cmd is {row[idx[1]].strip()!r}: a speed step is a whole "
                    f"number in -{MAX_STEP}..{MAX_STEP} (0 = stop)"
                )
            rows.append((t, s, th))
    except csv.Error as exc:
        raise DataError(f"{source}: line {reader.line_num}: not valid CSV ({exc})") from None
    if not rows:
        raise DataError(f"{source}: no data rows after the header")
    arr = np.asarray(rows, dtype=float)
    return validate_camera_log(CameraLog(arr[:, 0], arr[:, 1].astype(np.int64), arr[:, 2], source))


def validate_camera_log(log: CameraLog) -> CameraLog:
    """Check time increases evenly, there are enough rows and the camera moved; return ``log``."""
    src = log.source or "<data>"
    if log.n < MIN_ROWS:
        raise DataError(f"{src}: only {log.n} rows; at least {MIN_ROWS} command periods are needed")
    for name, arr in (("t", log.t_s), ("theta", log.theta_rad)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise DataError(f"{src}: line {bad[0] + 2}: {name} is {arr[bad[0]]!r}")
    check_clock(log.t_s, src, SAMPLING_TOLERANCE, "command period")
    if not np.any(log.step != 0):
        raise DataError(f"{src}: speed_cmd is 0 on every row: the camera was never driven")
    return log


def read_camera_log(path: str | Path) -> CameraLog:
    """Read a camera log from ``path``."""
    return parse_camera_log(read_text(path), str(path))


def format_camera_log(log: CameraLog) -> str:
    """The log as CSV text."""
    out = io.StringIO()
    out.write("t,speed_cmd,theta\n")
    for t, s, th in zip(log.t_s, log.step, log.theta_rad, strict=True):
        out.write(f"{t:.6f},{int(s)},{th:.9g}\n")
    return out.getvalue()
