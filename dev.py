#!/usr/bin/env python3
"""Set up and run the project: ``python3 dev.py serve`` (the console on the simulated rig),
``python3 dev.py test`` (the whole test suite), or install it for production with
``python3 dev.py install [--prefix /opt/3dat]``. Needs only Python 3.11+.

Setup (serve, test, setup) is idempotent: it creates ``.venv`` in the checkout, installs the
project editable with its dev extras at the pinned versions of ``requirements.lock``, and, when
running as root with apt-get available, the Debian packages the project uses (espeak-ng and sox
for simulated speech; chromium for the browser tests).

``install`` is what a room computer or a container gets: a virtual environment in
``<prefix>/.venv`` holding the project built as a wheel (not editable: the checkout can go away),
its runtime dependencies at the versions pinned in ``requirements.lock`` and nothing of the dev
extras (no test tools, no Playwright, no browser); as root with apt-get, the Debian packages the
service uses (espeak-ng, sox, libportaudio2). The service runs ``<prefix>/.venv/bin/tracker serve``
(deploy/3dat-console.service).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
PY = VENV / "bin" / "python"
STAMP = VENV / ".setup-stamp"
APT_SERVE = ["espeak-ng", "sox"]
APT_TEST = ["espeak-ng", "sox", "chromium"]
APT_RUNTIME = ["espeak-ng", "sox", "libportaudio2"]
# The program each Debian package provides (how we tell whether it is installed); a library
# package is asked of dpkg.
APT_BINARY = {"espeak-ng": "espeak-ng", "sox": "sox", "chromium": "chromium"}
DEFAULT_PREFIX = "/opt/3dat"
# Distributions of the dev extras that a production install must not contain.
DEV_ONLY = ("pytest", "playwright", "hypothesis", "schemathesis", "mypy", "ruff", "pytest-asyncio")


def run(cmd: list[str], **kw: object) -> None:
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, **kw)  # type: ignore[call-overload]


def apt_installed(package: str) -> bool:
    if package in APT_BINARY:
        return shutil.which(APT_BINARY[package]) is not None
    if not shutil.which("dpkg-query"):
        return False
    query = subprocess.run(["dpkg-query", "-W", "-f=${Status}", package], capture_output=True, text=True)
    return query.returncode == 0 and "install ok installed" in query.stdout


def apt_install(packages: list[str]) -> None:
    missing = [p for p in packages if not apt_installed(p)]
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
        warm_up()
        STAMP.write_text(digest)
    apt_install(apt_packages)


def warm_up() -> None:
    """Compile the twin and the workbench into numba's cache (``tracker warm-up``), so that the
    first diagnosis is not a minute and a half slower; a failure here is only a note (the
    tests or the service show any real problem)."""
    try:
        run([str(PY), "-m", "tracker", "warm-up"])
    except subprocess.CalledProcessError:
        print("note: tracker warm-up failed; numba compiles on first use instead", flush=True)


def install(prefix: Path, apt: bool = True) -> Path:
    """The production install into ``prefix`` (see the module doc); returns its ``tracker``."""
    if sys.version_info < (3, 11):  # noqa: UP036
        sys.exit(f"Python 3.11 or newer is needed (this is {sys.version.split()[0]})")
    prefix = prefix.resolve()
    venv_py = prefix / ".venv" / "bin" / "python"
    if not venv_py.exists():
        run([sys.executable, "-m", "venv", str(prefix / ".venv")])
    pip = [str(venv_py), "-m", "pip", "--disable-pip-version-check"]
    with tempfile.TemporaryDirectory(prefix="3dat-wheel-") as wheel_dir:
        # Built outside the checkout (it may be read-only); its data files carry static/ and
        # examples/ (pyproject.toml), so the service needs nothing from the checkout.
        run([*pip, "wheel", "-q", "--no-deps", "-w", wheel_dir, str(ROOT)])
        wheel = next(Path(wheel_dir).glob("*.whl"))
        run([*pip, "uninstall", "-q", "-y", "3dat-console"])  # the same version, rebuilt
        run([*pip, "install", "-q", "-c", str(ROOT / "requirements.lock"), str(wheel)])
    check_runtime_only(venv_py)
    if apt:
        apt_install(APT_RUNTIME)
    tracker = prefix / ".venv" / "bin" / "tracker"
    print(f"installed: {tracker} (run it as the unit does: deploy/3dat-console.service)", flush=True)
    return tracker


def check_runtime_only(venv_py: Path) -> None:
    """Fail when the environment holds a dev tool, or the installed code does not import."""
    probe = (
        "import importlib.metadata as m, sys\n"
        f"bad = [d for d in {DEV_ONLY!r} if d in {{x.metadata['Name'].lower() for x in m.distributions()}}]\n"
        "import app.main, tracker.engine\n"
        "sys.exit('dev tools installed: ' + ', '.join(bad) if bad else 0)\n"
    )
    run([str(venv_py), "-c", probe], cwd="/")


def main(argv: list[str]) -> int:
    if not argv or argv[0] not in {"serve", "test", "setup", "install"}:
        print(__doc__)
        return 2
    cmd, rest = argv[0], argv[1:]
    if cmd == "install":
        parser = argparse.ArgumentParser(prog="dev.py install", description="the production install")
        parser.add_argument("--prefix", default=DEFAULT_PREFIX, help=f"where .venv goes ({DEFAULT_PREFIX})")
        parser.add_argument("--no-apt", action="store_true", help="do not install Debian packages")
        args = parser.parse_args(rest)
        install(Path(args.prefix), apt=not args.no_apt)
        return 0
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
