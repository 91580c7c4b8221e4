"""Evaluation: the counterbalanced plan, starting and stopping trials, their ticks."""

from __future__ import annotations

import json
from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, Path, Request
from fastapi.responses import Response
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from backend import activity, audit, tick_queries
from backend.activity import ensure_idle
from backend.api.deps import CurrentUser, RuntimeDep, SessionDep, access
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND, conflict, invalid, one_or_404
from backend.api.params import MAX_ID, SessionId, StudyId
from backend.counterbalance import blinded_labels, controller_order
from backend.db.evidence import LockEvent, ModelSetRecord, Trial, UtilitySetRecord
from backend.db.models import ConditionLabel, Participant, StudySession
from backend.schemas.evidence import (
    LockEventOut,
    TrialOut,
    TrialPlanIn,
    TrialStartIn,
    TrialStopIn,
)
from controller.config import SettingError
from controller.factory import NEEDS_MODELS

router = APIRouter(tags=["trials"], responses={**AUTH_RESPONSES, **NOT_FOUND})

TrialId = Annotated[int, Path(ge=1, le=MAX_ID, description="trial id")]


def _position(db: SessionDep, participant: Participant) -> int:
    ids = list(db.scalars(select(Participant.id).where(Participant.study_id ==
                                                       participant.study_id)
                          .order_by(Participant.id)))
    return ids.index(participant.id)


@router.post("/api/sessions/{session_id}/trials/plan", response_model=list[TrialOut],
             status_code=201, responses=CONFLICT)
def plan_trials(session_id: SessionId, body: TrialPlanIn, user: CurrentUser,
                db: SessionDep) -> list[Trial]:
    """Create the session's trials: UMC and PEC in the order this participant's place in
    the study gives (balanced across participants), then E-UMC; each on every task.
    Also assigns the blinded labels the participant will see."""
    sess = one_or_404(db, StudySession, session_id, "session")
    if sess.kind != "evaluation":
        conflict("kind", f"session {sess.id} is a {sess.kind} session, not evaluation")
    if db.scalar(select(Trial.id).where(Trial.session_id == session_id)) is not None:
        conflict("trials", f"session {sess.id} already has a plan")
    for key, model, entity in (("model_set_id", ModelSetRecord, "model set"),
                               ("utility_set_id", UtilitySetRecord, "utility set")):
        ref = getattr(body, key)
        if ref is not None and db.get(model, ref) is None:
            invalid(["body", key], f"{entity} {ref} does not exist")
    participant = one_or_404(db, Participant, sess.participant_id, "participant")
    order = controller_order(_position(db, participant), body.include_eumc)
    labels = blinded_labels(order)
    existing = {c.controller: c.label for c in db.scalars(
        select(ConditionLabel).where(ConditionLabel.participant_id == participant.id))}
    for controller, label in labels.items():
        if controller not in existing:
            db.add(ConditionLabel(participant_id=participant.id, label=label,
                                  controller=controller))
    trials = []
    n = 0
    for controller in order:
        for task in body.tasks:
            trials.append(Trial(session_id=session_id, controller=controller, task=task,
                                planned_order=n, status="planned",
                                model_set_id=body.model_set_id if controller in NEEDS_MODELS
                                else None,
                                utility_set_id=body.utility_set_id if controller in NEEDS_MODELS
                                else None))
            n += 1
    db.add_all(trials)
    db.flush()
    audit.record(db, user, "plan", "session", session_id,
                 {"order": order, "tasks": body.tasks, "labels": labels})
    db.commit()
    return trials


@router.get("/api/sessions/{session_id}/trials", response_model=list[TrialOut])
def list_trials(session_id: SessionId, user: CurrentUser, db: SessionDep) -> list[Trial]:
    """The session's trials in planned order."""
    one_or_404(db, StudySession, session_id, "session")
    return list(db.scalars(select(Trial).where(Trial.session_id == session_id)
                           .order_by(Trial.planned_order)))


@router.get("/api/trials/{trial_id}", response_model=TrialOut)
def get_trial(trial_id: TrialId, user: CurrentUser, db: SessionDep) -> Trial:
    """One trial with its configuration snapshot."""
    return one_or_404(db, Trial, trial_id, "trial")


@router.post("/api/trials/{trial_id}/start", response_model=TrialOut, responses=CONFLICT)
async def start_trial(trial_id: TrialId, body: TrialStartIn, user: CurrentUser,
                      db: SessionDep, runtime: RuntimeDep) -> Trial:
    """Run the trial's controller with its model and utility sets, at the session's
    precompression; the exact configuration is stored with the trial. 409 while another
    trial or recording runs (checked and started under the runtime's activity lock; the
    database's unique index refuses a second running trial in any case)."""
    async with runtime.activity:
        try:
            return await _start_trial(trial_id, body, user, db, runtime)
        except IntegrityError:
            db.rollback()
            # The worker may already run the refused trial's controller: back to none.
            if runtime.supervisor.state.alive:
                try:
                    await runtime.switch_controller("none", runtime.controller_config("none"))
                except RuntimeError:
                    pass
            conflict("trial", "another trial is running: the database refused a second")


async def _start_trial(trial_id: int, body: TrialStartIn, user: CurrentUser,
                       db: SessionDep, runtime: RuntimeDep) -> Trial:
    trial = one_or_404(db, Trial, trial_id, "trial")
    if trial.status != "planned":
        conflict("status", f"trial {trial.id} is {trial.status}; plan a new one to repeat it")
    ensure_idle(db)
    sess = one_or_404(db, StudySession, trial.session_id, "session")
    overrides: dict[str, Any] = {"precompression_pct": sess.precompression_pct}
    if body.rate_hz is not None:
        overrides.update(umc_rate_hz=body.rate_hz, eumc_triggered_rate_hz=body.rate_hz,
                         pec_rate_hz=body.rate_hz)
    try:
        config = runtime.controller_config(trial.controller, overrides)
    except SettingError as exc:
        invalid(["body", "rate_hz" if exc.field.endswith("rate_hz") else exc.field],
                exc.problem)
    snapshot: dict[str, Any] = {"controller": trial.controller, "task": trial.task,
                                "device": {"kind": runtime.settings.device_kind,
                                           "seed": runtime.settings.device_seed,
                                           "script": runtime.settings.device_script}}
    if trial.controller in NEEDS_MODELS:
        ms = db.get(ModelSetRecord, trial.model_set_id) if trial.model_set_id else None
        us = db.get(UtilitySetRecord, trial.utility_set_id) if trial.utility_set_id else None
        if ms is None or ms.document is None:
            conflict("model_set_id", "the trial needs a fitted model set")
        if us is None or us.document is None:
            conflict("utility_set_id", "the trial needs a computed utility set")
        if abs(us.precompression_pct - sess.precompression_pct) > 1e-9:
            conflict("utility_set_id", f"utilities were computed for {us.precompression_pct:g} "
                     f"% but the session runs at {sess.precompression_pct:g} %")
        config.pop("models_path", None)
        config.pop("utilities_path", None)
        config["models"] = ms.document
        config["utilities"] = us.document
        snapshot["model_set"] = {"id": ms.id, "name": ms.name,
                                 "version": ms.document.get("version")}
        snapshot["utility_set"] = {"id": us.id, "name": us.name,
                                   "precompression_pct": us.precompression_pct,
                                   "human_source": us.human_source,
                                   "other_rule": us.document.get("meta", {}).get("other_rule")}
    if trial.controller == "eumc" and config["settings"].get("calibration") is None:
        conflict("calibration", "the E-UMC needs a calibration: have the participant stand "
                 "still and POST /api/worker/calibrate")
    snapshot["settings"] = config["settings"]
    if body.duration_s is not None:
        snapshot["duration_s"] = body.duration_s
    try:
        run_id = await runtime.switch_controller(
            trial.controller, config,
            max_ticks=None if body.duration_s is None else round(body.duration_s * 100))
    except RuntimeError as exc:
        # No trial without its controller, and no controller without its trial: a
        # switch that may still take effect later is countermanded.
        runtime.supervisor.set_controller("none", runtime.controller_config("none"))
        conflict("worker", str(exc))
    trial.run_id = run_id
    trial.status = "running"
    trial.started_at = datetime.now(UTC)
    trial.config_snapshot = snapshot
    audit.record(db, user, "start", "trial", trial.id, {"run_id": run_id})
    db.commit()
    await runtime.lab.trial_marker(db, trial, "trial_start")  # LSL marker, stored
    return trial


@router.post("/api/trials/{trial_id}/stop", response_model=TrialOut, responses=CONFLICT)
async def stop_trial(trial_id: TrialId, body: TrialStopIn, request: Request,
                     user: CurrentUser, db: SessionDep, runtime: RuntimeDep) -> Trial:
    """End the trial as completed or aborted; the worker returns to recording mode
    (no locks); the trial's tick count, quality flags (device time gaps, time going
    backwards) and lock events are derived from its stored ticks. 409 if it is no
    longer running (e.g. `interrupted` because its worker stopped)."""
    async with runtime.activity:
        return await _stop_trial(trial_id, body, request, user, db, runtime)


async def _stop_trial(trial_id: int, body: TrialStopIn, request: Request,
                      user: CurrentUser, db: SessionDep, runtime: RuntimeDep) -> Trial:
    trial = one_or_404(db, Trial, trial_id, "trial")
    if trial.status != "running":
        conflict("status", f"trial {trial.id} is {trial.status}, not running")
    if runtime.supervisor.state.alive:
        try:
            await runtime.switch_controller("none", runtime.controller_config("none"))
        except RuntimeError:
            pass  # the worker died during the trial: its ticks up to then are stored
    runtime.recorder.flush()
    if not activity.close_trial(db, request.app.state.engine, trial.id, body.outcome,
                                body.reason):
        db.refresh(trial)  # closed meanwhile: its worker stopped
        conflict("status", f"trial {trial.id} is {trial.status}, not running")
    db.refresh(trial)
    audit.record(db, user, "stop", "trial", trial.id, body.model_dump())
    db.commit()
    await runtime.lab.trial_marker(db, trial, "trial_stop")  # LSL marker, stored
    return trial


@router.get("/api/trials/{trial_id}/lock-events", response_model=list[LockEventOut])
def trial_lock_events(trial_id: TrialId, user: CurrentUser, db: SessionDep
                      ) -> list[LockEvent]:
    """The trial's lock events in time order."""
    one_or_404(db, Trial, trial_id, "trial")
    return list(db.scalars(select(LockEvent).where(LockEvent.trial_id == trial_id)
                           .order_by(LockEvent.t, LockEvent.id)))


def _run_of(db: SessionDep, trial_id: int) -> int:
    trial = one_or_404(db, Trial, trial_id, "trial")
    if trial.run_id is None:
        conflict("status", f"trial {trial.id} has not run")
    return trial.run_id


@router.get("/api/trials/{trial_id}/ticks.csv", response_class=Response, responses={
    200: {"content": {"text/csv": {}}, "description": "one row per tick"}, **CONFLICT})
def trial_ticks_csv(trial_id: TrialId, request: Request, user: CurrentUser,
                    db: SessionDep) -> Response:
    """Every tick of the trial as CSV (columns and units: the study export's data
    dictionary); empty cells are values not computed at that tick."""
    text = tick_queries.csv_text(request.app.state.engine, _run_of(db, trial_id))
    return Response(text, media_type="text/csv", headers={
        "Content-Disposition": f'attachment; filename="trial-{trial_id}-ticks.csv"'})


@router.get("/api/trials/{trial_id}/ticks.json", response_class=Response, responses={
    200: {"content": {"application/json": {}}, "description": "columns of ticks"},
    **CONFLICT})
def trial_ticks_json(trial_id: TrialId, request: Request, user: CurrentUser,
                     db: SessionDep) -> Response:
    """Every tick of the trial as JSON columns (`field -> list`, null where not computed)."""
    cols = tick_queries.columns(request.app.state.engine, _run_of(db, trial_id))
    body = {k: [None if isinstance(x, float) and x != x else x for x in v.tolist()]
            for k, v in cols.items()}
    return Response(json.dumps({"trial_id": trial_id, "columns": body}),
                    media_type="application/json")


@router.get("/api/studies/{study_id}/export.zip", response_class=Response,
            openapi_extra=access("owner"), responses={
    200: {"content": {"application/zip": {}},
          "description": "tables as CSV, documents as JSON, ticks, data dictionary"}})
def export_study(study_id: StudyId, request: Request, user: CurrentUser, db: SessionDep
                 ) -> Response:
    """The whole study as a zip (see README.md inside for every column's meaning)."""
    from backend.db.models import Study
    from backend.export import study_zip

    one_or_404(db, Study, study_id, "study")
    runtime: Any = request.app.state.runtime
    runtime.recorder.flush()
    site = getattr(getattr(request.state, "grant", None), "site", None)
    data = study_zip(request.app.state.engine, study_id, site=site)
    audit.record(db, user, "export", "study", study_id, {"bytes": len(data)})
    db.commit()
    return Response(data, media_type="application/zip", headers={
        "Content-Disposition": f'attachment; filename="study-{study_id}.zip"'})
