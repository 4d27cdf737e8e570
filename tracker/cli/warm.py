"""``tracker warm-up``: compile the simulator's and the workbench's code into numba's cache.

::

    tracker warm-up

Run once after an install (``dev.py`` does it when it sets up), with the same
``NUMBA_CACHE_DIR`` as the service, so that the first diagnosis is not a minute and a half slower.
"""

from __future__ import annotations

import argparse
import os

from tracker.cli import command_help
from tracker.warm import warm_up


def _run(args: argparse.Namespace) -> int:
    where = os.environ.get("NUMBA_CACHE_DIR") or "the package's __pycache__ folders"
    print(
        f"compiling the twin, diagnosis and fit into numba's cache ({where}); once, about 1-2 min", flush=True
    )
    result = warm_up(lambda text: print(f"  {text}", flush=True))
    print(f"done in {result.total_s:.1f} s", flush=True)
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = subparsers.add_parser(
        "warm-up",
        help=command_help("warm-up"),
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.set_defaults(func=_run)
