"""Run a command as systemd runs the unit: everything read-only but the state folder and a
private temporary folder (``ProtectSystem=strict``, ``StateDirectory=``, ``PrivateTmp=``).

As root, a private mount namespace (``unshare``) remounts ``/`` read-only after binding the two
writable folders onto themselves, which is what systemd does. Without root the installed tree is
made read-only with ``chmod -R a-w`` instead (weaker: the rest of the disk stays writable).
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from tests.deploy.unit_file import ROOT

_MOUNT_SCRIPT = (
    'IFS=:; for d in $SANDBOX_RW; do mount --bind "$d" "$d" || exit 97; done; unset IFS; '
    "mount -o remount,bind,ro / || exit 97; "
    'cd "$SANDBOX_CWD" && exec "$@"'
)


def namespaces_work() -> bool:
    """True when this process may make a private read-only view of the disk (root, unshare)."""
    if os.geteuid() != 0 or not shutil.which("unshare"):
        return False
    probe = subprocess.run(
        ["unshare", "--mount", "--propagation", "private", "sh", "-c",
         "mount -o remount,bind,ro / && ! touch /.probe"],
        capture_output=True,
    )
    return probe.returncode == 0


def sandboxed(
    cmd: list[str], writable: list[Path], cwd: Path, readonly_tree: Path
) -> tuple[list[str], dict[str, str]]:
    """The command line (and extra environment) that runs ``cmd`` with only ``writable`` writable."""
    if namespaces_work():
        wrapped = ["unshare", "--mount", "--propagation", "private", "sh", "-c", _MOUNT_SCRIPT, "sh", *cmd]
        return wrapped, {"SANDBOX_RW": ":".join(str(p) for p in writable), "SANDBOX_CWD": str(cwd)}
    if os.geteuid() == 0:
        pytest.skip("root without mount namespaces: cannot make the install read-only")
    make_readonly(readonly_tree)
    return cmd, {}


def make_readonly(tree: Path) -> None:
    for path in [tree, *tree.rglob("*")]:
        if not path.is_symlink():
            mode = path.stat().st_mode
            path.chmod(mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


def light_install(prefix: Path, wheel_dir: Path) -> Path:
    """The project installed as ``dev.py install`` installs it (the wheel, not editable) into
    ``prefix/.venv``, its dependencies borrowed from this interpreter's environment instead of
    downloaded. Returns the venv's python."""
    venv = prefix / ".venv"
    base = getattr(sys, "_base_executable", sys.executable)
    subprocess.run([base, "-m", "venv", "--without-pip", str(venv)], check=True)
    site = venv / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    deps = next(p for p in sys.path if p.endswith("site-packages") and Path(p).is_dir())
    (site / "zz_borrowed_dependencies.pth").write_text(deps + "\n", encoding="utf-8")
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
    subprocess.run([*pip, "wheel", "-q", "--no-deps", "-w", str(wheel_dir), str(ROOT)], check=True)
    wheel = next(wheel_dir.glob("*.whl"))
    subprocess.run(
        [*pip, "--python", str(venv / "bin" / "python"), "install", "-q", "--no-deps", "--no-index",
         "--ignore-installed", str(wheel)],
        check=True,
    )
    return venv / "bin" / "python"
