"""Stale compiled callers are dropped when an inlined source changes (numba keys on one file)."""

from pathlib import Path

from tracker.control.numba_cache import purge_stale_cache


def test_callers_cache_is_purged_once_per_source_change(tmp_path: Path) -> None:
    for name in (
        "loop.controller_step-1.py311.nbi",
        "closed_loop.run_chunk-2.py311.1.nbc",
        "limits.g-3.py311.nbi",
    ):
        (tmp_path / name).write_text("x")
    (tmp_path / "inlined-sources.sha256").write_text("an older hash")
    assert purge_stale_cache(tmp_path)
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == ["inlined-sources.sha256", "limits.g-3.py311.nbi"]
    (tmp_path / "loop.controller_step-1.py311.nbi").write_text("fresh")
    assert not purge_stale_cache(tmp_path)
    assert (tmp_path / "loop.controller_step-1.py311.nbi").exists()
