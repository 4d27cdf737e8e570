"""Lending the service's drive to a job (the camera's speed-table identification, the DC rig's
friction-ID sweep): what must hold before a job takes it over, and the refusal while it has it.
Each refusal is a 409 :class:`app.errors.Conflict` naming what is in the way."""

from __future__ import annotations

from typing import Any

from app.errors import Conflict


def check_free(engine: Any, drive: Any, what: str, job: str) -> None:  # noqa: ANN401 - engine, driver
    """``drive`` (the engine's ``what``: "camera" or "rig") may be lent to ``job``: tracking off,
    no fault latched, not lent already, connected and enabled."""
    st = engine.status()
    if st.tracking:
        raise Conflict(f"tracking is on: turn it off (PUT /api/v1/tracking) before the {job} takes "
                       f"the {what} over", mode=st.mode)
    if drive.faults():
        raise Conflict(f"drive fault latched ({'; '.join(drive.faults())}): clear it first", mode=st.mode)
    if drive.held_by is not None:
        raise Conflict(f"the {what} is already taken over by {drive.held_by}")
    if not (drive.enabled and drive.ready):
        raise Conflict(f"{what} {drive.spec.url} is {drive.state}{'' if drive.enabled else ', disabled'}: "
                       "it must be connected and enabled", mode=st.mode)


def refuse_while_held(engine: Any) -> None:  # noqa: ANN401 - the engine
    """Conflict while the camera or rig is taken over by a job (turning tracking on would do
    nothing)."""
    holder = getattr(getattr(engine, "driver", None), "held_by", None)
    if holder is not None:
        raise Conflict(f"the drive is taken over by {holder}: cancel the job or wait for it to finish")
