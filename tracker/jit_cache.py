"""Where numba keeps compiled code, chosen before anything is compiled, so that a place it cannot
write never stops the engine.

The engine's kernels are compiled with ``cache=True``. numba writes that cache next to the source
(``__pycache__``), or under ``NUMBA_CACHE_DIR``, or in the user's cache folder; when none is
writable (a read-only install under systemd's ``ProtectSystem=strict`` with no
``NUMBA_CACHE_DIR``) decorating a kernel raises ``RuntimeError: cannot cache function ...: no
locator available`` and the service cannot start. :func:`settle_numba_cache` runs when
``tracker`` is imported (before numba is) and picks, in order: ``NUMBA_CACHE_DIR`` when it is
writable, the source tree's ``__pycache__`` when writable, the user's cache folder, a private
temporary folder for this process (compiled code is then not kept across restarts), and when
nothing at all can be written, no cache (every start compiles).
"""

from __future__ import annotations

import hashlib
import logging
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

log = logging.getLogger("tracker.jit_cache")

ENV = "NUMBA_CACHE_DIR"
_PACKAGE_DIR = Path(__file__).resolve().parent


@dataclass(frozen=True, slots=True)
class CacheChoice:
    """Where compiled kernels go: ``kind`` is ``"env"``, ``"in-tree"``, ``"user"``,
    ``"temporary"`` or ``"none"``; ``path`` the folder (None for in-tree and none); ``note``
    why, for the log."""

    kind: str
    path: Path | None
    note: str


def writable_dir(path: Path) -> bool:
    """True when ``path`` exists or can be created, and a file can be written in it."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError:
        return False
    return True


def _user_cache_dir(environ: dict[str, str] | os._Environ[str]) -> Path | None:
    base = environ.get("XDG_CACHE_HOME") or (
        str(Path(environ["HOME"]) / ".cache") if environ.get("HOME") else ""
    )
    return Path(base) / "numba" if base else None


def choose_cache(
    environ: dict[str, str] | os._Environ[str] = os.environ, package_dir: Path = _PACKAGE_DIR
) -> CacheChoice:
    """Where numba can keep compiled code, first writable of the places the module doc lists."""
    requested = environ.get(ENV, "").strip()
    note = ""
    if requested:
        if writable_dir(Path(requested)):
            return CacheChoice("env", Path(requested), f"{ENV}={requested}")
        note = f"{ENV}={requested} is not writable; "
    if writable_dir(package_dir / "__pycache__"):
        return CacheChoice("in-tree", None, note + f"beside the sources in {package_dir}")
    user = _user_cache_dir(environ)
    if user is not None and writable_dir(user):
        return CacheChoice("user", user, note + f"the sources are read-only; user cache {user}")
    try:
        tmp = Path(tempfile.mkdtemp(prefix="tracker-numba-"))
    except OSError:
        return CacheChoice("none", None, note + "nothing is writable: compiled code is not cached")
    return CacheChoice(
        "temporary", tmp, note + f"nothing lasting is writable: compiled code kept in {tmp} for this run only"
    )


def settle_numba_cache(environ: Any = os.environ) -> CacheChoice:
    """Point numba at the cache :func:`choose_cache` picks (sets ``NUMBA_CACHE_DIR``); with no
    writable place at all, make ``cache=True`` compile without caching instead of failing."""
    choice = choose_cache(environ)
    if choice.path is not None:
        environ[ENV] = str(choice.path)
        numba_config = sys.modules.get("numba.core.config")
        if numba_config is not None:  # numba read the environment already
            numba_config.CACHE_DIR = str(choice.path)  # type: ignore[attr-defined]
    elif choice.kind == "in-tree":
        environ.pop(ENV, None)
    else:
        environ.pop(ENV, None)
        _compile_without_cache()
    if choice.kind in {"temporary", "none"} or "not writable" in choice.note:
        log.warning("numba cache: %s", choice.note)
    return choice


def _compile_without_cache() -> None:
    """Make a dispatcher whose cache cannot be located fall back to numba's no-op cache."""
    from numba.core import caching, dispatcher

    original = dispatcher.Dispatcher.enable_caching
    if getattr(original, "_tracker_fallback", False):
        return

    def enable_caching(self: Any) -> None:
        try:
            original(self)
        except RuntimeError as exc:
            if "no locator available" not in str(exc):
                raise
            self._cache = caching.NullCache()

    enable_caching._tracker_fallback = True  # type: ignore[attr-defined]
    dispatcher.Dispatcher.enable_caching = enable_caching  # type: ignore[method-assign]


def cache_dir_for(source_dir: Path) -> Path:
    """The folder numba caches the kernels of ``source_dir``'s modules in (numba's own rule:
    ``NUMBA_CACHE_DIR/<folder name>_<sha1 of its absolute path>``, else its ``__pycache__``)."""
    base = os.environ.get(ENV, "").strip()
    if not base:
        return source_dir / "__pycache__"
    absolute = os.path.abspath(source_dir)
    digest = hashlib.sha1(absolute.encode()).hexdigest()  # noqa: S324 - numba's path key, not security
    return Path(base) / f"{os.path.split(absolute)[-1]}_{digest}"

