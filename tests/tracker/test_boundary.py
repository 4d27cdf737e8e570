"""The engine never imports a web framework (STYLE.md: the engine/web boundary)."""

import subprocess
import sys


def test_importing_the_engine_loads_no_web_framework() -> None:
    code = (
        "import sys, importlib, pkgutil, tracker\n"
        "for m in pkgutil.walk_packages(tracker.__path__, 'tracker.'):\n"
        "    if m.name.startswith('tracker.cli') or m.name == 'tracker.__main__':\n"
        "        continue\n"
        "    importlib.import_module(m.name)\n"
        "bad = sorted(n for n in ('fastapi', 'starlette', 'uvicorn', 'viser') if n in sys.modules)\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"tracker imported {out.stdout.strip()}"
