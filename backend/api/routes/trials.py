"""Evaluation: the counterbalanced plan, starting and stopping trials, their ticks."""

from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Path
from fastapi.responses import Response

from backend.analysis import tick_queries
from backend.analysis.export import study_zip
from backend.api.deps import (
    CurrentUser,
    EngineDep,
    LabDep,
    RuntimeDep,
    SessionDep,
    SiteDep,
    access,
)
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND
from backend.api.params import MAX_ID, SessionId, StudyId
from backend.db.evidence_tables import LockEvent, Trial
from backend.emg.muscle_results import export_files
from backend.schemas.documents import TickColumnsOut
from backend.schemas.evidence import (
    LockEventOut,
    TrialOut,
    TrialPlanIn,
    TrialStartIn,
    TrialStopIn,
)
from backend.study import studies
from backend.study import trials as trials_service
from controller.tick_codec import json_columns

router = APIRouter(tags=["trials"], responses={**AUTH_RESPONSES, **NOT_FOUND})

TrialId = Annotated[int, Path(ge=1, le=MAX_ID, description="trial id")]


@router.post("/api/sessions/{session_id}/trials/plan", response_model=list[TrialOut],
             status_code=201, responses=CONFLICT)
def plan_trials(session_id: SessionId, body: TrialPlanIn, user: CurrentUser,
                db: SessionDep) -> list[Trial]:
    """Create the session's trials: UMC and PEC in the order this participant's place in
    the study gives (balanced across participants), then E-UMC; each on every task.
    Also assigns the blinded labels the participant will see."""
    return trials_service.plan(db, user, session_id, body)


@router.get("/api/sessions/{session_id}/trials", response_model=list[TrialOut])
def list_trials(session_id: SessionId, user: CurrentUser, db: SessionDep) -> list[Trial]:
    """The session's trials in planned order."""
    return trials_service.session_trials(db, session_id)


@router.get("/api/trials/{trial_id}", response_model=TrialOut)
def get_trial(trial_id: TrialId, user: CurrentUser, db: SessionDep) -> Trial:
    """One trial with its configuration snapshot."""
    return trials_service.get(db, trial_id)


@router.post("/api/trials/{trial_id}/start", response_model=TrialOut, responses=CONFLICT,
             openapi_extra=access("device"))
async def start_trial(trial_id: TrialId, body: TrialStartIn, user: CurrentUser,
                      db: SessionDep, runtime: RuntimeDep, lab: LabDep) -> Trial:
    """Run the trial's controller with its model and utility sets, at the session's
    precompression; the exact configuration is stored with the trial. 409 while another
    trial or recording runs (checked and started under the runtime's activity lock; the
    database's unique index refuses a second running trial in any case)."""
    return await trials_service.start(db, user, runtime, lab, trial_id, body)


@router.post("/api/trials/{trial_id}/stop", response_model=TrialOut, responses=CONFLICT)
async def stop_trial(trial_id: TrialId, body: TrialStopIn, engine: EngineDep,
                     user: CurrentUser, db: SessionDep, runtime: RuntimeDep,
                     lab: LabDep) -> Trial:
    """End the trial as completed or aborted; the worker returns to recording mode
    (no locks); the trial's tick count, quality flags (device time gaps, time going
    backwards) and lock events are derived from its stored ticks. 409 if it is no
    longer running (e.g. `interrupted` because its worker stopped)."""
    return await trials_service.stop(db, engine, user, runtime, lab, trial_id, body)


@router.get("/api/trials/{trial_id}/lock-events", response_model=list[LockEventOut])
def trial_lock_events(trial_id: TrialId, user: CurrentUser, db: SessionDep
                      ) -> list[LockEvent]:
    """The trial's lock events in time order."""
    return trials_service.lock_events(db, trial_id)


@router.get("/api/trials/{trial_id}/ticks.csv", response_class=Response, responses={
    200: {"content": {"text/csv": {}}, "description": "one row per tick"}, **CONFLICT})
def trial_ticks_csv(trial_id: TrialId, engine: EngineDep, user: CurrentUser,
                    db: SessionDep) -> Response:
    """Every tick of the trial as CSV (columns and units: the study export's data
    dictionary); empty cells are values not computed at that tick."""
    text = tick_queries.csv_text(engine, trials_service.run_of(db, trial_id))
    return Response(text, media_type="text/csv", headers={
        "Content-Disposition": f'attachment; filename="trial-{trial_id}-ticks.csv"'})


@router.get("/api/trials/{trial_id}/ticks.json", response_class=Response, responses={
    200: {"model": TickColumnsOut, "content": {"application/json": {}},
          "description": "columns of ticks"}, **CONFLICT})
def trial_ticks_json(trial_id: TrialId, engine: EngineDep, user: CurrentUser,
                     db: SessionDep) -> Response:
    """Every tick of the trial as JSON columns (`field -> list`, null where not computed)."""
    body = json_columns(tick_queries.columns(engine, trials_service.run_of(db, trial_id)))
    return Response(json.dumps({"trial_id": trial_id, "columns": body}),
                    media_type="application/json")


@router.get("/api/studies/{study_id}/export.zip", response_class=Response,
            openapi_extra=access("owner"), responses={
    200: {"content": {"application/zip": {}},
          "description": "tables as CSV, documents as JSON, ticks, data dictionary"}})
def export_study(study_id: StudyId, engine: EngineDep, site: SiteDep, user: CurrentUser,
                 db: SessionDep, runtime: RuntimeDep) -> Response:
    """The whole study as a zip (see README.md inside for every column's meaning)."""
    studies.get(db, study_id)
    runtime.recorder.flush()
    data = study_zip(engine, study_id, site=site, unblind=True,  # owners only
                     muscle_files=export_files(engine, study_id, site))
    studies.record_export(db, user, study_id, "export", {"bytes": len(data)})
    return Response(data, media_type="application/zip", headers={
        "Content-Disposition": f'attachment; filename="study-{study_id}.zip"'})
