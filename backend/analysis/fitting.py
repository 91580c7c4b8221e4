"""Fitting motion models and computing utility sets: checked, recorded with their
provenance, then computed in the background jobs' `study` lane (never queued behind
virtual cohorts).

The service behind `backend/api/routes/model_sets.py`; refusals are `backend.core.errors`.
A job's row is created in the caller's transaction (so the answer carries its id) and
updated from the job thread in its own transactions.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from sqlalchemy import Engine, select, update
from sqlalchemy.orm import Session, sessionmaker

from backend.analysis import tick_queries
from backend.analysis.jobs import JobRunner
from backend.core.errors import InvalidError
from backend.db import audit
from backend.db.evidence_tables import LiftSegment, ModelSetRecord, Recording, UtilitySetRecord
from backend.db.models import Participant, StudySession, User
from backend.schemas.evidence import ModelSetIn, ModelSetOut, UtilitySetOut
from controller.decision.utility_function import compute_utilities
from controller.human_data import HumanMotionData
from controller.intent.motion_model import fit_model_set as fit_models
from controller.tick_record import MODEL_NAMES

Computed = type[ModelSetRecord] | type[UtilitySetRecord]


def _set_row(sessions: sessionmaker[Session], model: Computed, row_id: int,
             **values: Any) -> None:
    """Update a model or utility set from the job thread (its own transaction)."""
    with sessions() as s:
        s.execute(update(model).where(model.id == row_id).values(**values))
        s.commit()


def _failure(sessions: sessionmaker[Session], model: Computed, row_id: int
             ) -> Callable[[str], None]:
    """What a failed job leaves on its row: status failed and the reason."""
    return lambda message: _set_row(sessions, model, row_id, status="failed",
                                    error=message[:2000])


def _study_of_recording(db: Session, recording_id: int) -> int:
    rec = db.get(Recording, recording_id)
    sess = db.get(StudySession, rec.session_id) if rec else None
    part = db.get(Participant, sess.participant_id) if sess else None
    return part.study_id if part else -1


def fit_model_set(db: Session, engine: Engine, sessions: sessionmaker[Session],
                  jobs: JobRunner, user: User, study_id: int, body: ModelSetIn
                  ) -> ModelSetOut:
    """Check the segments (this study's, labelled, at least two per motion), record the
    model set as `fitting` and queue the fit; the answer carries the job id."""
    ids = list(dict.fromkeys(body.segment_ids))
    segs = list(db.scalars(select(LiftSegment).where(LiftSegment.id.in_(ids))))
    unknown = sorted(set(ids) - {s.id for s in segs})
    if unknown:
        raise InvalidError.at(["body", "segment_ids"], f"unknown segment ids {unknown[:20]}")
    wrong_study = [s.id for s in segs if _study_of_recording(db, s.recording_id) != study_id]
    if wrong_study:
        raise InvalidError.at(["body", "segment_ids"],
                              f"segments {wrong_study[:20]} belong to another study")
    unlabelled = [s.id for s in segs if s.label not in MODEL_NAMES]
    if unlabelled:
        raise InvalidError.at(["body", "segment_ids"], f"segments {unlabelled[:20]} are not "
                              f"labelled as {', '.join(MODEL_NAMES)}")
    counts = {m: sum(s.label == m for s in segs) for m in MODEL_NAMES}
    short = {m: c for m, c in counts.items() if c < 2}
    if short:
        raise InvalidError.at(["body", "segment_ids"],
                              f"need at least 2 segments per motion, got {short}")
    params: dict[str, Any] = {"latent_dim": body.latent_dim,
                              "explained_variance": body.explained_variance, "counts": counts}
    row = ModelSetRecord(study_id=study_id, name=body.name, status="fitting", params=params,
                         segment_ids=ids, created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "model_set", row.id, {"name": body.name, **params})
    db.commit()
    plan = [(s.id, s.label, s.recording_id, s.start, s.end) for s in segs]
    ms_id = row.id

    def work(progress: Any) -> str:
        demos: dict[str, list[np.ndarray]] = {m: [] for m in MODEL_NAMES}
        demo_ids: dict[str, list[str]] = {m: [] for m in MODEL_NAMES}
        cache: dict[int, np.ndarray] = {}
        for k, (sid, label, rid, start, end) in enumerate(plan):
            if rid not in cache:
                with sessions() as s:
                    rec = s.get(Recording, rid)
                    assert rec is not None and rec.run_id is not None
                    cols = tick_queries.columns(engine, rec.run_id, rec.first_tick_id,
                                                rec.last_tick_id)
                cache[rid] = np.column_stack([cols["q_left"], cols["q_right"]])
            seg = cache[rid][start:end + 1]
            if np.isnan(seg).any():
                raise ValueError(f"segment {sid} contains bad samples; edit its edges")
            demos[label].append(seg)
            demo_ids[label].append(f"segment:{sid}")
            progress(0.8 * (k + 1) / len(plan))
        mset = fit_models(demos, q=body.latent_dim,
                             explained_variance=body.explained_variance,
                             version=f"study-{study_id}-modelset-{ms_id}", demo_ids=demo_ids,
                             meta={"study_id": study_id, "name": body.name})
        _set_row(sessions, ModelSetRecord, ms_id, document=mset.to_json(), status="ready")
        return f"fitted {sum(len(v) for v in demos.values())} demonstrations"

    job_id, _ = jobs.submit(
        "fit_model_set", ms_id, work, _failure(sessions, ModelSetRecord, ms_id),
        owner_id=user.id)
    return ModelSetOut.model_validate(row).model_copy(update={"job_id": job_id})


def compute_utility_set(jobs: JobRunner, sessions: sessionmaker[Session], db: Session,
                      user: User, study_id: int, name: str,
                      pct: float, human: HumanMotionData, source: str) -> UtilitySetOut:
    """Record the utility set as `computing` (with the human data it is computed from)
    and queue the computation; the answer carries the job id."""
    row = UtilitySetRecord(study_id=study_id, name=name, precompression_pct=pct,
                           human_source=source, status="computing",
                           human_data=human.to_json(), created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "utility_set", row.id,
                 {"name": name, "precompression_pct": pct, "human_source": source})
    db.commit()
    us_id = row.id

    def work(progress: Any) -> str:
        uset = compute_utilities(human, pct, progress=progress)
        _set_row(sessions, UtilitySetRecord, us_id, document=uset.to_json(), status="ready")
        return f"utilities for {pct:g} % precompression"

    job_id, _ = jobs.submit(
        "compute_utilities", us_id, work, _failure(sessions, UtilitySetRecord, us_id),
        owner_id=user.id)
    return UtilitySetOut.model_validate(row).model_copy(update={"job_id": job_id})
