"""The job pool's shutdown lets go of its progress queue and cancel flags, so their POSIX
semaphores are unlinked then. Left to the process's exit they never were: uvicorn ends the
service by re-raising its SIGTERM, which skips multiprocessing's exit handlers, and the
resource tracker reported "4 leaked semaphore objects" at every shutdown."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from app.workers import WorkerPool

ROOT = Path(__file__).resolve().parents[2]


def _semaphore_names(pool: WorkerPool) -> list[str]:
    q, flags = pool._progress, pool._cancel
    locks = (q._rlock, q._wlock, q._sem, flags.get_lock())  # type: ignore[union-attr]
    return [lock._semlock.name for lock in locks if lock is not None]


@pytest.mark.skipif(not Path("/dev/shm").is_dir(), reason="POSIX semaphores are not files here")
def test_shutdown_unlinks_the_pools_semaphores() -> None:
    pool = WorkerPool(1)
    names = _semaphore_names(pool)
    assert len(names) == 4 and all(Path(f"/dev/shm/sem.{n.lstrip('/')}").exists() for n in names)
    pool.shutdown()
    assert not [n for n in names if Path(f"/dev/shm/sem.{n.lstrip('/')}").exists()]


def test_a_service_ended_by_sigterm_after_the_shutdown_leaks_no_semaphore() -> None:
    code = ("import os, signal\nfrom app.workers import WorkerPool\n"
            "if __name__ == '__main__':\n"
            "    p = WorkerPool(1)\n    p.shutdown()\n"
            "    os.kill(os.getpid(), signal.SIGTERM)  # as uvicorn ends: no exit handlers\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=60, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == -signal.SIGTERM, proc.stderr
    assert "leaked semaphore" not in proc.stderr, proc.stderr
