"""Long use: the wearer works, the controller runs, everything is logged as in a trial.

A long-use session (`kind = "long_use"`) has no trial plan. Each time the experimenter
starts the controller for the wearer's work, a trial of task `long_use` is added to the
session and started through the very path a planned trial takes
(`backend.study.trials.start`): its own worker run, so every tick and decision is
stored; the configuration snapshot; the hardware profile; the LSL start and stop
markers. It is stopped like any trial (`POST /api/trials/{id}/stop`), which derives its
tick count, quality flags and lock events; the experimenter's markers during it
(`POST /api/sessions/{id}/markers`) are stored with it. Nothing is blinded: long use
compares no conditions.
"""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db.evidence_tables import ModelSetRecord, Trial, UtilitySetRecord
from backend.db.models import Participant, StudySession, User
from backend.lab.hub import Lab
from backend.live.runtime import Runtime
from backend.schemas.evidence import TrialStartIn
from backend.schemas.wearers import LONG_USE_TASK, LongUseStartIn
from backend.study import activity
from backend.study import trials as trials_service
from controller.controllers import registry
from controller.controllers.factory import needs_models


def controllers() -> tuple[str, ...]:
    """The controllers a long-use session may run: those of the trial plans, never a
    baseline (a baseline never locks: nothing to use) nor the idle one."""
    return tuple(r.name for r in registry.planned())


def _set_of(db: Session, part: Participant,
            model: type[ModelSetRecord] | type[UtilitySetRecord],
            ref: int | None, key: str, entity: str) -> int | None:
    """A set the wearer may run: of their study, ready, and a personal model set only
    if it is their own (422 as in a plan)."""
    if ref is None:
        return None
    row: ModelSetRecord | UtilitySetRecord | None = (
        db.get(ModelSetRecord, ref) if model is ModelSetRecord else db.get(UtilitySetRecord, ref))
    if row is None or row.study_id != part.study_id:
        raise InvalidError.at(["body", key], f"{entity} {ref} does not exist in this study")
    if isinstance(row, ModelSetRecord) and row.kind == "personal" \
            and row.participant_id != part.id:
        raise InvalidError.at(["body", key], f"model set {ref} is a personal model set of "
                              f"another participant, not {part.code}")
    if row.status != "ready" or row.document is None:
        raise ConflictError(key, f"{entity} {ref} is {row.status}, not ready")
    return ref


async def start(db: Session, user: User, runtime: Runtime, lab: Lab, session_id: int,
                body: LongUseStartIn) -> Trial:
    """Add a long-use trial to the session and start it as a trial starts; a refused
    start leaves no trial behind (it never ran)."""
    sess = db.get(StudySession, session_id)
    if sess is None:
        raise NotFoundError("session", session_id)
    if sess.kind != "long_use":
        raise ConflictError("kind", f"session {sess.id} is a {sess.kind} session; long use "
                            "runs in a session of kind long_use")
    name = body.controller.strip().lower()
    if name not in controllers():
        raise InvalidError.at(["body", "controller"], f"{body.controller!r} cannot run in "
                              f"long use; choose one of {', '.join(controllers())}")
    part = db.get(Participant, sess.participant_id)
    assert part is not None
    sets = needs_models(name)
    ms = _set_of(db, part, ModelSetRecord, body.model_set_id, "model_set_id",
                 "model set")
    us = _set_of(db, part, UtilitySetRecord, body.utility_set_id, "utility_set_id",
                 "utility set")
    if sets and (ms is None or us is None):
        missing = "model_set_id" if ms is None else "utility_set_id"
        raise InvalidError.at(["body", missing], f"the {registry.label(name)} needs a ready "
                              "model set and utility set of the study")
    activity.ensure_idle(db)  # a clear 409 before a trial row exists
    order = db.scalar(select(func.count()).select_from(Trial)
                      .where(Trial.session_id == sess.id)) or 0
    trial = Trial(session_id=sess.id, controller=name, task=LONG_USE_TASK,
                  planned_order=int(order), status="planned",
                  model_set_id=ms if sets else None, utility_set_id=us if sets else None)
    db.add(trial)
    db.commit()
    try:
        return await trials_service.start(db, user, runtime, lab, trial.id, TrialStartIn(
            rate_hz=body.rate_hz, duration_s=body.duration_s))
    except BaseException:
        db.rollback()
        row = db.get(Trial, trial.id)
        if row is not None and row.status == "planned":
            db.delete(row)
            db.commit()
        raise
