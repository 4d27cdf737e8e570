"""The model workbench: compare the model with measurements, diagnose missing effects, refit."""

from pathlib import Path

from tracker.control.numba_cache import purge_stale_cache
from tracker.jit_cache import cache_dir_for

_HERE = Path(__file__).resolve().parent
# The closed-loop recorder and the k-step shooting inline the plant's ``advance``: numba would
# keep their compiled code after plant/simulate.py changed.
purge_stale_cache(
    cache_dir_for(_HERE),
    (_HERE.parent / "plant" / "simulate.py", _HERE / "experiments.py", _HERE / "kstep.py"),
    ("experiments.", "kstep."),
)
