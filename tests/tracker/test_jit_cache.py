"""Where numba caches compiled kernels: the first writable of NUMBA_CACHE_DIR, the sources, the
user's cache, a temporary folder; with nothing writable, compiling without a cache."""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from tracker.jit_cache import cache_dir_for, choose_cache


def _blocked(tmp_path: Path, name: str) -> Path:
    """A path no one can create, root included: it lies under a regular file."""
    blocker = tmp_path / f"{name}-is-a-file"
    blocker.write_text("")
    return blocker / name


def test_a_writable_numba_cache_dir_wins(tmp_path: Path) -> None:
    choice = choose_cache({"NUMBA_CACHE_DIR": str(tmp_path / "c")}, package_dir=tmp_path / "pkg")
    assert (choice.kind, choice.path) == ("env", tmp_path / "c")


def test_the_sources_when_no_cache_dir_is_set(tmp_path: Path) -> None:
    choice = choose_cache({}, package_dir=tmp_path / "pkg")
    assert choice.kind == "in-tree" and (tmp_path / "pkg" / "__pycache__").is_dir()


def test_an_unwritable_cache_dir_falls_through_to_the_user_cache(tmp_path: Path) -> None:
    env = {"NUMBA_CACHE_DIR": str(_blocked(tmp_path, "c")), "HOME": str(tmp_path / "home")}
    choice = choose_cache(env, package_dir=_blocked(tmp_path, "pkg"))
    assert (choice.kind, choice.path) == ("user", tmp_path / "home" / ".cache" / "numba")
    assert "is not writable" in choice.note


def test_a_readonly_install_without_home_gets_a_temporary_cache(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    choice = choose_cache({"HOME": str(_blocked(tmp_path, "home"))}, package_dir=_blocked(tmp_path, "pkg"))
    assert choice.kind == "temporary" and choice.path is not None
    assert choice.path.parent == tmp_path / "tmp"


def test_nothing_writable_means_no_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(_blocked(tmp_path, "tmp")))
    choice = choose_cache({}, package_dir=_blocked(tmp_path, "pkg"))
    assert (choice.kind, choice.path) == ("none", None)


KERNEL = "from numba import njit\n@njit(cache=True)\ndef f(x):\n    return x + 1\n"
# A kernel whose source file does not exist: numba finds no place to cache it, as under a
# read-only install with no writable cache folder.
PROBE = (
    "import sys\n"
    "if sys.argv[1] == 'fallback':\n"
    "    from tracker.jit_cache import _compile_without_cache; _compile_without_cache()\n"
    "ns = {}\n"
    f"exec(compile({KERNEL!r}, '/nonexistent/kernel.py', 'exec'), ns)\n"
    "print(ns['f'](41))\n"
)


def test_a_kernel_with_no_cache_location_compiles_without_a_cache() -> None:
    before = subprocess.run([sys.executable, "-c", PROBE, "stock"], capture_output=True, text=True)
    assert before.returncode != 0 and "no locator available" in before.stderr
    after = subprocess.run([sys.executable, "-c", PROBE, "fallback"], capture_output=True, text=True)
    assert after.returncode == 0, after.stderr
    assert after.stdout.strip() == "42"


def test_the_cache_folder_follows_numba_s_rule(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    assert cache_dir_for(tmp_path / "control") == tmp_path / "control" / "__pycache__"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "nc"))
    from numba.core.caching import _CacheLocator

    subpath = _CacheLocator.get_suitable_cache_subpath(str(tmp_path / "control" / "loop.py"))
    expected = tmp_path / "nc" / subpath
    assert cache_dir_for(tmp_path / "control") == expected
