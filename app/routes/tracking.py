"""PUT /tracking: follow the talker (audio target source) or hold the manual target.

Turning tracking on is refused with 503 while a drive fault is latched; turning it off always works.
The choice is stored and restored at the next start (app/console_state.py).
"""

from __future__ import annotations

from fastapi import APIRouter

from app.auth import Operator
from app.lending import refuse_while_held
from app.schemas import TrackingIn, TrackingOut
from app.service import Svc

router = APIRouter(tags=["tracking"])


@router.put("/tracking", response_model=TrackingOut, summary="Turn talker tracking on or off")
async def put_tracking(body: TrackingIn, svc: Svc, who: Operator) -> TrackingOut:
    if body.enabled:
        svc.engine.require_no_fault()
        refuse_while_held(svc.engine)  # a speed-table identification job drives the camera
        # Re-enabling tracking ends the manual override: only the holder of manual control (or
        # anyone when nobody holds it) may do that; 409 otherwise.
        svc.lock.acquire(who)
        svc.engine.set_tracking(True)
        svc.lock.release(who)
    else:
        svc.engine.set_tracking(False)
    svc.console.tracking_changed(body.enabled)
    await svc.audit.record(who, "tracking.set", "", {"enabled": body.enabled})
    st = svc.engine.status()
    return TrackingOut(tracking=bool(st.tracking), mode=str(st.mode))
