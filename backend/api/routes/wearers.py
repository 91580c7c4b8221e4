"""Use outside the lab: a long-use session's controller, and a wearer's progress over
sessions (the per-wearer page's data)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from backend.analysis import wearer_progress
from backend.api.deps import CurrentUser, LabDep, RuntimeDep, SessionDep, access
from backend.api.errors import AUTH_RESPONSES, BODY, CONFLICT, NOT_FOUND
from backend.api.params import ParticipantId, SessionId
from backend.core.errors import InvalidError
from backend.db.evidence_tables import Trial
from backend.schemas.evidence import TrialOut
from backend.schemas.wearers import LongUseStartIn, WearerProgressOut
from backend.study import long_use

router = APIRouter(tags=["wearers"], responses={**AUTH_RESPONSES, **NOT_FOUND})


@router.post("/api/sessions/{session_id}/long-use", response_model=TrialOut,
             status_code=201, responses={**CONFLICT, **BODY}, openapi_extra=access("device"))
async def start_long_use(session_id: SessionId, body: LongUseStartIn, user: CurrentUser,
                         db: SessionDep, runtime: RuntimeDep, lab: LabDep) -> Trial:
    """Run a controller for the wearer's work in a long-use session: a trial of task
    `long_use` is added and started as a planned trial starts (its own run, every tick
    and decision stored, the configuration snapshot). Stop it with
    `POST /api/trials/{id}/stop`; mark events with `POST /api/sessions/{id}/markers`.
    409 if the session is not a long-use session or something already runs."""
    return await long_use.start(db, user, runtime, lab, session_id, body)


@router.get("/api/participants/{participant_id}/progress", response_model=WearerProgressOut,
            responses=CONFLICT)
def get_progress(participant_id: ParticipantId, user: CurrentUser,
                 db: SessionDep, runtime: RuntimeDep,
                 controller: Annotated[str | None, Query(
                     max_length=32, description="only this controller's long-use trials")
                 ] = None) -> WearerProgressOut:
    """The wearer's long-use sessions in time order and, per metric (lifts per hour,
    recognition and lock rates, time to lock, false positives per hour of walking and
    of stairs), each session's value with its 95 % interval and the least-squares trend
    per session with its 95 % interval. 409 for a withdrawn participant."""
    if controller is not None and controller not in long_use.controllers():
        raise InvalidError.at(["query", "controller"], f"unknown controller {controller!r}; "
                              f"choose one of {', '.join(long_use.controllers())}")
    runtime.recorder.flush()  # the newest ticks of a just-stopped trial
    return wearer_progress.wearer_progress(db, participant_id, controller)
