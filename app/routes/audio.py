"""The room's audio: the camera operator's policy (read, set, reset), the talkers followed, the
sound card's input devices.

GET /audio/policy (viewer): the values in force, where they came from and, for each setting,
its unit, allowed range, default and meaning. PUT (engineer): change some of them; applied to
the running tracker from its next frame (no restart) and stored (restored at the next start);
a value out of range is refused with 422 naming the field, its range and meaning, and nothing
changes. DELETE (engineer): forget the stored values (back to the config file's or defaults).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from pydantic import BaseModel, ConfigDict, Field, create_model

from app.auth import Engineer, Viewer
from app.errors import Refused
from app.policy import describe_range_public, fields_json, policy_to_json
from app.service import Service, Svc
from tracker.errors import DriverFault, OutOfRange

router = APIRouter(tags=["audio"])


def _policy_in() -> type[BaseModel]:
    """The PUT body: every setting optional, described from the catalogue (names, units,
    ranges, meanings); values are checked by :func:`app.policy.policy_from_json`."""
    fields: dict[str, Any] = {
        f["name"]: (Any, Field(None, description=f"{f['meaning']}; {describe_range_public(f)}"))
        for f in fields_json()
    }
    model: type[BaseModel] = create_model(
        "PolicyIn", __config__=ConfigDict(extra="forbid"), **fields)
    return model


PolicyIn = _policy_in()


class PolicyOut(BaseModel):
    values: dict[str, float] = Field(description="the policy in force (seconds, degrees, counts)")
    source: str = Field(description="where it came from: default, config (the config file) or "
                                    "stored (set through this API)")
    fields: list[dict[str, Any]] = Field(description="each setting's name, unit, min, max, "
                                                     "default and meaning")


def policy_out(svc: Service) -> PolicyOut:
    return PolicyOut(values=policy_to_json(svc.policy.policy), source=svc.policy.source,
                     fields=fields_json())


@router.get("/audio/policy", response_model=PolicyOut, summary="The camera operator's policy")
async def get_policy(svc: Svc, who: Viewer) -> PolicyOut:
    return policy_out(svc)


@router.put("/audio/policy", response_model=PolicyOut,
            summary="Change the camera operator's policy (applied at once, stored)")
async def put_policy(body: PolicyIn, svc: Svc, who: Engineer) -> PolicyOut:  # type: ignore[valid-type]
    changes = {k: getattr(body, k) for k in body.model_fields_set}  # type: ignore[attr-defined]
    try:
        svc.policy.update(changes)
    except OutOfRange as exc:
        raise Refused(str(exc), field=exc.name, allowed={"min": exc.low, "max": exc.high,
                                                         "unit": exc.unit}) from None
    return policy_out(svc)


@router.delete("/audio/policy", response_model=PolicyOut,
               summary="Forget the stored policy: back to the config file's (or the defaults)")
async def delete_policy(svc: Svc, who: Engineer) -> PolicyOut:
    svc.policy.reset()
    return policy_out(svc)


@router.get("/audio/talkers", summary="The talkers the tracker has followed, who is speaking")
async def get_talkers(svc: Svc, who: Viewer) -> dict[str, Any]:
    return {"talkers": talkers_of(svc)}


def talkers_of(svc: Service) -> list[dict[str, Any]]:
    state = getattr(svc.audio, "talkers_state", None)
    return state() if callable(state) else []


@router.get("/audio/devices", summary="The sound card's input devices (PortAudio)")
async def get_devices(svc: Svc, who: Engineer) -> dict[str, Any]:
    """An empty list with a note when PortAudio or every input device is missing."""
    import dataclasses

    from tracker.audio.capture import list_input_devices

    try:
        devices = list_input_devices()
    except DriverFault as exc:
        return {"devices": [], "note": str(exc)}
    note = None if devices else "PortAudio lists no input device"
    return {"devices": [dataclasses.asdict(d) for d in devices], "note": note}
