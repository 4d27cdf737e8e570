"""What the job workers run (:mod:`app.workers`): friction-ID on plain arguments with a plain,
JSON-ready result. (The workbench's and practice rig's heavy work is in :mod:`app.heavy`, run
by :mod:`app.work`.)
"""

from __future__ import annotations

from typing import Any

from app.modelio import model_from_json, plain


def friction_job(progress: Any, cancel: Any, rig_config: str | None, hidden_json: dict[str, Any] | None,
                 hidden_axis: str, axis: str, voltages: int = 10) -> dict[str, Any]:
    """Friction-ID on a simulated rig built like the live one (``rig_config``) or like the
    practice rig (``hidden_json`` on ``hidden_axis``)."""
    from tracker.drivers.sim import SimDriver, rig_models
    from tracker.workbench.experiments import friction_id

    if hidden_json is not None:
        hidden = model_from_json(hidden_json)
        models = dict(rig_models())
        models[hidden_axis] = hidden if hidden.has("quantization") else hidden.with_effect("quantization")
        driver = SimDriver.from_models(models)
    elif rig_config is not None:
        driver = SimDriver.from_config(rig_config)
    else:
        driver = SimDriver()
    result = friction_id.run_friction_id(driver, axis=axis, voltages_per_direction=voltages,
                                         progress=progress, cancel=cancel)
    out: dict[str, Any] = plain(result.to_dict())
    return out
