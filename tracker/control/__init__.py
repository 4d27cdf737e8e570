"""Controllers of one axis: design with python-control, the compiled loop, shaping and limits."""

from tracker.control.numba_cache import purge_stale_cache

purge_stale_cache()
