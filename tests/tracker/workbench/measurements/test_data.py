"""Measurement logs: round trip and clear errors for bad files."""

import numpy as np
import pytest

from tracker.errors import DataError
from tracker.workbench.measurements.data import Measurement, format_log, parse_log

N = 300


def good_text() -> str:
    return format_log(Measurement(np.arange(N) * 1e-3, np.sin(np.arange(N) * 0.01), np.zeros(N)))


def test_a_log_survives_a_round_trip() -> None:
    m = parse_log(good_text())
    assert m.n == N and m.dt_s == pytest.approx(1e-3)
    assert np.allclose(m.u_v, np.sin(np.arange(N) * 0.01))


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda s: s.replace("theta", "angle", 1), "line 1: missing column theta"),
        (lambda s: s.replace("\n0.001,", "\n0.001,nan,", 1), "line 3"),
        (lambda s: s.replace("\n0.002,", "\n0.0025,", 1), "uneven sampling"),
        (lambda s: s.replace("\n0.002,", "\n0.0005,", 1), "time does not increase"),
        (lambda s: s.replace("\n0.002,", "\n0.0\r02,", 1), "not valid CSV"),
        (lambda s: "\n".join(s.splitlines()[:50]), "only 49 samples"),
        (lambda s: "", "empty file"),
    ],
    ids=["missing-column", "nan", "uneven", "not-increasing", "stray-carriage-return", "too-short", "empty"],
)
def test_bad_logs_raise_a_data_error_that_says_where(edit, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(DataError, match=message):
        parse_log(edit(good_text()), "run.csv")
