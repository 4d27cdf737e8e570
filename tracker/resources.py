"""Where the project's data folders (``examples``, ``static``) are, in a checkout or an install.

A source checkout (or an editable install) keeps them beside the packages; the wheel that
``dev.py install`` builds ships them as data files under ``<prefix>/share/3dat-console/``
(pyproject.toml, ``[tool.setuptools.data-files]``), so an installed service does not need the
source tree.
"""

from __future__ import annotations

import sys
from pathlib import Path

SHARE_NAME = "3dat-console"
_CHECKOUT = Path(__file__).resolve().parents[1]


def project_dir(name: str) -> Path:
    """The project's data folder ``name`` (``"examples"`` or ``"static"``).

    Beside the packages when they run from a checkout (marked by its ``pyproject.toml``),
    otherwise ``sys.prefix/share/3dat-console/<name>`` (the installed wheel's data files).
    """
    if (_CHECKOUT / "pyproject.toml").is_file() and (_CHECKOUT / name).is_dir():
        return _CHECKOUT / name
    return Path(sys.prefix) / "share" / SHARE_NAME / name
