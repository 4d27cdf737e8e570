"""``tracker warm-up`` compiles the twin, the diagnosis and the fit into numba's cache, so that
a fresh install's first diagnosis does not spend a minute and a half compiling."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import tracker
from tracker.warm import WarmUp

PACKAGE = Path(tracker.__file__).resolve().parent
# The kernels a diagnosis and a fit run: the k-step judge, the screening's load in a dead band,
# the closed loop of the twin, the state observer.
KERNEL_DIRS = (
    "workbench/compare",
    "workbench/diagnose",
    "workbench/experiments",
    "workbench/measurements",
    "plant",
)


def _indexed(cache: Path, source_dir: Path) -> set[str]:
    """The modules of ``source_dir`` with a numba index in ``cache`` (numba's own layout)."""
    found: set[str] = set()
    for sub in cache.iterdir():
        if sub.name.startswith(source_dir.name + "_"):
            found |= {p.name.split(".")[0] for p in sub.glob("*.nbi")}
    return found


@pytest.mark.slow
def test_warm_up_fills_an_empty_cache_with_the_workbenchs_kernels(tmp_path: Path) -> None:
    cache = tmp_path / "numba"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    proc = subprocess.run(
        [sys.executable, "-m", "tracker", "warm-up"],
        cwd=PACKAGE.parent,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "diagnose (every candidate):" in proc.stdout and "done in" in proc.stdout
    for rel in KERNEL_DIRS:
        assert _indexed(cache, PACKAGE / rel), f"no compiled kernel of tracker/{rel} in {cache}"
    assert {"kstep", "screening"} <= _indexed(cache, PACKAGE / "workbench/diagnose")
    assert "floor" in _indexed(cache, PACKAGE / "workbench/compare")  # the residual test's replay


def test_the_warm_up_result_adds_its_stages() -> None:
    result = WarmUp((("a", 1.5), ("b", 0.25)))
    assert result.total_s == pytest.approx(1.75)
