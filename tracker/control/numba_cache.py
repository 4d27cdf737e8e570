"""Drop numba's on-disk cache of the compiled loop when a function it inlines has changed.

numba keys each cached function on its own source file only. ``loop.controller_step`` inlines
the guard (limits.py, envelope.py) and the shaper (trajectory.py); ``closed_loop.run_chunk`` inlines the
controller and the plant (plant/simulate.py). Editing any of those would leave the callers'
caches silently stale, so on import we hash the sources and purge the callers' cache files
when the hash moved.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from tracker.jit_cache import cache_dir_for

_HERE = Path(__file__).resolve().parent
_SOURCES = (
    _HERE / "loop.py",
    _HERE / "limits.py",
    _HERE / "envelope.py",
    _HERE / "belt_guard.py",
    _HERE / "trajectory.py",
    _HERE / "observer.py",
    _HERE / "closed_loop.py",
    _HERE.parent / "plant" / "simulate.py",
)
_CALLERS = ("loop.", "closed_loop.")


def purge_stale_cache(
    cache_dir: Path | None = None,
    sources: tuple[Path, ...] = _SOURCES,
    callers: tuple[str, ...] = _CALLERS,
) -> bool:
    """Remove the callers' cache files if the inlined sources changed. Returns True if purged.

    ``cache_dir`` holds the callers' cache (default: where numba caches this package, its
    ``__pycache__`` or under ``NUMBA_CACHE_DIR``); other packages whose compiled loops inline the
    plant pass their own (``tracker.workbench``).
    """
    cache = cache_dir or cache_dir_for(_HERE)
    digest = hashlib.sha256()
    for src in sources:
        try:
            digest.update(src.read_bytes())
        except OSError:
            return False
    stamp = cache / "inlined-sources.sha256"
    try:
        if stamp.read_text(encoding="ascii") == digest.hexdigest():
            return False
    except OSError:
        pass
    try:
        cache.mkdir(parents=True, exist_ok=True)
        for f in cache.iterdir():
            if f.name.startswith(callers) and ".nb" in f.suffix:
                f.unlink(missing_ok=True)
        stamp.write_text(digest.hexdigest(), encoding="ascii")
    except OSError:
        return False  # read-only install: numba then cannot cache either
    return True
