"""3DAT engine: pan/tilt physics, simulation, control, audio localization and the model workbench.

This package never imports a web framework; ``app/`` serves it.
"""

__version__ = "0.1.0"

# Before any kernel is compiled: a cache numba cannot write must not stop the engine.
from tracker.jit_cache import settle_numba_cache  # noqa: E402

NUMBA_CACHE = settle_numba_cache()
