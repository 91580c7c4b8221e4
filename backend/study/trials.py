"""The evaluation trials: the counterbalanced plan, and starting and stopping a trial on
the live path with exactly the configuration stored beside it.

The service behind `backend/api/routes/trials.py`; refusals are `backend.core.errors`.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Engine, delete, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.core.resources import version
from backend.db.evidence_tables import ModelSetRecord, Trial, UtilitySetRecord
from backend.db.models import ConditionLabel, Participant, StudySession, User
from backend.live.runtime import Runtime
from backend.schemas.evidence import TrialPlanIn, TrialStartIn, TrialStopIn
from backend.study import activity, audit, hardware_profiles
from backend.study.counterbalance import blinded_labels, controller_order
from controller.config import SettingError
from controller.controllers import registry
from controller.controllers.factory import needs_models
from controller.controllers.spec import ControllerSpec
from controller.device.base import SAMPLE_PERIOD_S


def _get(db: Session, model: Any, key: int, entity: str) -> Any:
    row = db.get(model, key)
    if row is None:
        raise NotFoundError(entity, key)
    return row


def _position(db: Session, participant: Participant) -> int:
    ids = list(db.scalars(select(Participant.id).where(Participant.study_id ==
                                                       participant.study_id)
                          .order_by(Participant.id)))
    return ids.index(participant.id)


def plan(db: Session, user: User, session_id: int, body: TrialPlanIn) -> list[Trial]:
    """Create the session's trials in the counterbalanced order and assign the blinded
    labels; commits."""
    sess: StudySession = _get(db, StudySession, session_id, "session")
    if sess.kind != "evaluation":
        raise ConflictError("kind", f"session {sess.id} is a {sess.kind} session, not "
                            "evaluation")
    existing_plan = list(db.scalars(select(Trial).where(Trial.session_id == session_id)
                                    .order_by(Trial.planned_order)))
    replaced = [t.id for t in existing_plan]
    if existing_plan and not body.replace:
        raise ConflictError("trials", f"session {sess.id} already has a plan; send "
                            '"replace": true to replace it (allowed while none of its '
                            "trials has started)")
    ms = db.get(ModelSetRecord, body.model_set_id) if body.model_set_id else None
    us = db.get(UtilitySetRecord, body.utility_set_id) if body.utility_set_id else None
    _check_ready("model_set_id", "model set", body.model_set_id, ms)
    _check_ready("utility_set_id", "utility set", body.utility_set_id, us)
    if existing_plan:
        _discard_plan(db, sess, existing_plan)
    participant: Participant = _get(db, Participant, sess.participant_id, "participant")
    order = controller_order(_position(db, participant), body.include_eumc)
    labels = blinded_labels(order)
    existing = {c.controller: c.label for c in db.scalars(
        select(ConditionLabel).where(ConditionLabel.participant_id == participant.id))}
    for controller, label in labels.items():
        if controller not in existing:
            db.add(ConditionLabel(participant_id=participant.id, label=label,
                                  controller=controller))
    trials: list[Trial] = []
    for controller in order:
        sets = needs_models(controller)
        for task in body.tasks:
            trials.append(Trial(session_id=session_id, controller=controller, task=task,
                                planned_order=len(trials), status="planned",
                                model_set_id=body.model_set_id if sets else None,
                                utility_set_id=body.utility_set_id if sets else None))
    db.add_all(trials)
    db.flush()
    audit.record(db, user, "plan", "session", session_id,
                 {"order": order, "tasks": body.tasks, "labels": labels,
                  "replaced_trials": replaced})
    db.commit()
    return trials


def _check_ready(key: str, entity: str, ref: int | None,
                 row: ModelSetRecord | UtilitySetRecord | None) -> None:
    """A plan names only sets that exist and are ready: one still fitting may yet fail,
    and trials planned with it could never start."""
    if ref is None:
        return
    if row is None:
        raise InvalidError.at(["body", key], f"{entity} {ref} does not exist")
    if row.status != "ready" or row.document is None:
        raise ConflictError(key, f"{entity} {ref} is {row.status}, not ready: plan with a "
                            f"ready {entity}" + (f" ({row.error})" if row.error else ""))


def _discard_plan(db: Session, sess: StudySession, trials: list[Trial]) -> None:
    """Make way for a new plan (asked for with `replace`), only while no trial of the
    old one has started: a started trial's ticks, configuration and outcome are
    evidence."""
    started = [f"{t.id} ({t.status})" for t in trials if t.status != "planned"]
    if started:
        raise ConflictError("trials", f"session {sess.id}'s plan cannot be replaced: "
                            f"trial(s) {', '.join(started[:20])} have started and are kept "
                            "with their data")
    ids = [t.id for t in trials]
    # Conditional: a trial started by a concurrent request since the read stays.
    gone = db.execute(delete(Trial).where(Trial.id.in_(ids), Trial.status == "planned")
                      .execution_options(synchronize_session="fetch"))
    if gone.rowcount != len(ids):  # type: ignore[attr-defined]
        db.rollback()
        raise ConflictError("trials", f"session {sess.id}'s plan cannot be replaced: a "
                            "trial of it has just started")


def trial_spec(db: Session, runtime: Runtime, trial: Trial, sess: StudySession,
               rate_hz: float | None) -> tuple[ControllerSpec, dict[str, Any]]:
    """The trial's controller configuration and the snapshot stored with the trial:
    the server's defaults at the session's precompression, `rate_hz` for every
    controller if given, and the trial's own model and utility sets inline (so the
    stored snapshot is what ran, whatever the files hold later)."""
    overrides: dict[str, Any] = {"precompression_pct": sess.precompression_pct}
    if rate_hz is not None:
        overrides.update(umc_rate_hz=rate_hz, eumc_triggered_rate_hz=rate_hz,
                         pec_rate_hz=rate_hz)
    try:
        spec = runtime.controller_spec(trial.controller, overrides)
    except SettingError as exc:
        raise InvalidError.at(["body", "rate_hz" if exc.field.endswith("rate_hz")
                               else exc.field], exc.problem) from exc
    snapshot: dict[str, Any] = {"controller": trial.controller, "task": trial.task,
                                "device": {"kind": runtime.settings.device_kind,
                                           "seed": runtime.settings.device_seed,
                                           "script": runtime.settings.device_script}}
    if needs_models(trial.controller):
        ms = db.get(ModelSetRecord, trial.model_set_id) if trial.model_set_id else None
        us = db.get(UtilitySetRecord, trial.utility_set_id) if trial.utility_set_id else None
        if ms is None or ms.document is None:
            raise ConflictError("model_set_id", "the trial needs a fitted model set")
        if us is None or us.document is None:
            raise ConflictError("utility_set_id", "the trial needs a computed utility set")
        if abs(us.precompression_pct - sess.precompression_pct) > 1e-9:
            raise ConflictError("utility_set_id", f"utilities were computed for "
                                f"{us.precompression_pct:g} % but the session runs at "
                                f"{sess.precompression_pct:g} %")
        spec = replace(spec, models=ms.document, models_path=None,
                       utilities=us.document, utilities_path=None)
        snapshot["model_set"] = {"id": ms.id, "name": ms.name,
                                 "version": ms.document.get("version")}
        snapshot["utility_set"] = {"id": us.id, "name": us.name,
                                   "precompression_pct": us.precompression_pct,
                                   "human_source": us.human_source,
                                   "other_rule": us.document.get("meta", {}).get("other_rule")}
    settings = spec.settings.to_json()
    if registry.needs_calibration(trial.controller) and settings.get("calibration") is None:
        raise ConflictError("calibration", f"the {registry.label(trial.controller)} needs a "
                            "calibration: have the participant stand still and POST "
                            "/api/worker/calibrate")
    snapshot["settings"] = settings
    return spec, snapshot


async def start(db: Session, user: User, runtime: Runtime, trial_id: int,
                body: TrialStartIn) -> Trial:
    """Run the trial's controller and mark it running, under the runtime's activity
    lock; a second running trial refused by the database leaves the worker idle."""
    async with runtime.activity:
        try:
            return await _start(db, user, runtime, trial_id, body)
        except IntegrityError as exc:
            db.rollback()
            # The worker may already run the refused trial's controller: back to none.
            await runtime.idle()
            raise ConflictError("trial", "another trial is running: the database "
                                "refused a second") from exc


async def _start(db: Session, user: User, runtime: Runtime, trial_id: int,
                 body: TrialStartIn) -> Trial:
    trial: Trial = _get(db, Trial, trial_id, "trial")
    if trial.status != "planned":
        raise ConflictError("status", f"trial {trial.id} is {trial.status}; plan a new one "
                            "to repeat it")
    activity.ensure_idle(db)
    sess: StudySession = _get(db, StudySession, trial.session_id, "session")
    spec, snapshot = trial_spec(db, runtime, trial, sess, body.rate_hz)
    if body.duration_s is not None:
        snapshot["duration_s"] = body.duration_s
    snapshot["exostudy_version"] = version()
    try:
        run_id = await runtime.switch_controller(
            spec, max_ticks=None if body.duration_s is None
            else round(body.duration_s / SAMPLE_PERIOD_S))
    except RuntimeError as exc:
        # No trial without its controller, and no controller without its trial: a
        # switch that may still take effect later is countermanded.
        runtime.release()
        raise ConflictError("worker", str(exc)) from exc
    trial.run_id = run_id
    trial.status = "running"
    trial.started_at = datetime.now(UTC)
    trial.config_snapshot = snapshot
    trial.hardware_profile_id = hardware_profiles.active_id(db)
    audit.record(db, user, "start", "trial", trial.id, {"run_id": run_id})
    db.commit()
    await runtime.lab.trial_marker(db, trial, "trial_start")  # LSL marker, stored
    return trial


async def stop(db: Session, engine: Engine, user: User, runtime: Runtime, trial_id: int,
               body: TrialStopIn) -> Trial:
    """End a running trial as completed or aborted: the worker back to `none`, then its
    tick count, quality flags and lock events from the stored ticks."""
    async with runtime.activity:
        trial: Trial = _get(db, Trial, trial_id, "trial")
        if trial.status != "running":
            raise ConflictError("status", f"trial {trial.id} is {trial.status}, not running")
        await runtime.idle()  # a worker that died has stored the trial's ticks up to then
        runtime.recorder.flush()
        if not activity.close_trial(db, engine, trial.id, body.outcome, body.reason):
            db.refresh(trial)  # closed meanwhile: its worker stopped
            raise ConflictError("status", f"trial {trial.id} is {trial.status}, not running")
        db.refresh(trial)
        audit.record(db, user, "stop", "trial", trial.id, body.model_dump())
        db.commit()
        await runtime.lab.trial_marker(db, trial, "trial_stop")  # LSL marker, stored
        return trial
