"""The model workbench: compare the model with measurements, diagnose missing effects, refit.

Grouped by the steps of the loop a user walks:

- ``measurements/``: the CSV log, the EMPS benchmark, state estimation and inverse dynamics;
- ``compare/``: k-step prediction against a log, error by regime, residual tests;
- ``diagnose/``: screening every effect of the catalogue, judging candidates by simulation, the
  verdict and the evidence in words;
- ``fit/``: starting values and the nonlinear refit of every free parameter;
- ``experiments/``: closed-loop runs on the twin and the seed's friction-identification sweep;
- ``versions.py``: the model's versions, each refitted, with its figures kept.

What is specific to one physical effect lives in that effect's file in ``tracker/plant/effects/``.
"""

from pathlib import Path

from tracker.control.numba_cache import purge_stale_cache
from tracker.jit_cache import cache_dir_for

_HERE = Path(__file__).resolve().parent
_PLANT = _HERE.parent / "plant" / "simulate.py"
# The closed-loop recorder and the k-step shooting inline the plant's ``advance``: numba would
# keep their compiled code after plant/simulate.py changed.
purge_stale_cache(
    cache_dir_for(_HERE / "experiments"),
    (_PLANT, _HERE / "experiments" / "experiments.py", _HERE / "experiments" / "excite.py"),
    ("experiments.", "excite."),
)
purge_stale_cache(
    cache_dir_for(_HERE / "diagnose"),
    (_PLANT, _HERE / "diagnose" / "kstep.py"),
    ("kstep.",),
)
# The two-mass observer pass and the comparison's simulations inline it too.
purge_stale_cache(
    cache_dir_for(_HERE / "measurements"),
    (_PLANT, _HERE / "measurements" / "observed.py"),
    ("observed.",),
)
purge_stale_cache(
    cache_dir_for(_HERE / "compare"),
    (_PLANT, _HERE / "compare" / "compare.py", _HERE / "compare" / "floor.py"),
    ("compare.", "floor."),
)
