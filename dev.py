#!/usr/bin/env python3
"""Set up and run the project: ``python3 dev.py serve`` (the console on the simulated rig) or
``python3 dev.py test`` (the whole test suite). Needs only Python 3.11+.

Setup is idempotent: it creates ``.venv``, installs the project with the pinned versions of
``requirements.lock``, and, when running as root with apt-get available, the Debian packages the
project uses (espeak-ng and sox for simulated speech; chromium for the browser tests).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
PY = VENV / "bin" / "python"
STAMP = VENV / ".setup-stamp"
APT_SERVE = ["espeak-ng", "sox"]
APT_TEST = ["espeak-ng", "sox", "chromium"]
# The program each Debian package provides (how we tell whether it is installed).
APT_BINARY = {"espeak-ng": "espeak-ng", "sox": "sox", "chromium": "chromium"}


def run(cmd: list[str], **kw: object) -> None:
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, **kw)  # type: ignore[call-overload]


def apt_install(packages: list[str]) -> None:
    missing = [p for p in packages if not shutil.which(APT_BINARY[p])]
    if not missing:
        return
    if os.geteuid() != 0 or not shutil.which("apt-get"):
        print(f"note: please install {' '.join(missing)} (apt); continuing without them", flush=True)
        return
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    try:
        run(["apt-get", "update", "-qq"], env=env)
        run(["apt-get", "install", "-y", "-qq", "--no-install-recommends", *missing], env=env)
    except subprocess.CalledProcessError:
        print(f"note: apt-get could not install {' '.join(missing)}; continuing", flush=True)


def setup(apt_packages: list[str]) -> None:
    if sys.version_info < (3, 11):  # noqa: UP036 - dev.py is what runs on an older Python first
        sys.exit(f"Python 3.11 or newer is needed (this is {sys.version.split()[0]})")
    if not PY.exists():
        run([sys.executable, "-m", "venv", str(VENV)])
    digest = hashlib.sha256(
        (ROOT / "pyproject.toml").read_bytes() + (ROOT / "requirements.lock").read_bytes()
    ).hexdigest()
    if not STAMP.exists() or STAMP.read_text() != digest:
        run([str(PY), "-m", "pip", "install", "-q", "--upgrade", "pip"])
        run(
            [
                str(PY),
                "-m",
                "pip",
                "install",
                "-q",
                "-c",
                str(ROOT / "requirements.lock"),
                "-e",
                f"{ROOT}[dev]",
            ]
        )
        STAMP.write_text(digest)
    apt_install(apt_packages)


def main(argv: list[str]) -> int:
    if not argv or argv[0] not in {"serve", "test", "setup"}:
        print(__doc__)
        return 2
    cmd, rest = argv[0], argv[1:]
    os.chdir(ROOT)
    if cmd == "serve":
        setup(APT_SERVE)
        os.execv(str(VENV / "bin" / "tracker"), ["tracker", "serve", *rest])
    if cmd == "setup":
        setup(APT_TEST)
        return 0
    setup(APT_TEST)
    return subprocess.call([str(PY), "-m", "pytest", "-q", *rest])


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
