"""Model sets and utility sets: fitted and computed as background jobs, with provenance."""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, File, Form, Path, Request, UploadFile
from sqlalchemy import select, update
from sqlalchemy.orm import Session, sessionmaker

from backend import audit, tick_queries
from backend.api.deps import CurrentUser, SessionDep
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND, conflict, invalid, one_or_404
from backend.api.params import MAX_ID, StudyId
from backend.db.evidence import Job, LiftSegment, ModelSetRecord, Recording, UtilitySetRecord
from backend.db.models import Participant, Study, StudySession
from backend.human_data_csv import CsvError, parse_human_data
from backend.schemas.evidence import (
    JobOut,
    ModelSetIn,
    ModelSetOut,
    UtilityCurves,
    UtilitySetIn,
    UtilitySetOut,
)
from controller.human_data import HumanMotionData
from controller.motion_model import fit_model_set
from controller.tick import ACTION_NAMES, MODEL_NAMES
from controller.utilities import UtilitySet, compute_utilities

router = APIRouter(tags=["models"], responses={**AUTH_RESPONSES, **NOT_FOUND})

ModelSetId = Annotated[int, Path(ge=1, le=MAX_ID, description="model set id")]
UtilitySetId = Annotated[int, Path(ge=1, le=MAX_ID, description="utility set id")]
JobId = Annotated[int, Path(ge=1, le=MAX_ID, description="job id")]


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


@router.post("/api/studies/{study_id}/model-sets", response_model=ModelSetOut,
             status_code=202, responses=CONFLICT)
def fit_models(study_id: StudyId, body: ModelSetIn, request: Request, user: CurrentUser,
               db: SessionDep) -> ModelSetOut:
    """Fit PPCA motion models from labelled segments of this study's recordings. Returns
    at once with the job id; poll `GET /api/jobs/{job_id}`."""
    one_or_404(db, Study, study_id, "study")
    ids = list(dict.fromkeys(body.segment_ids))
    segs = list(db.scalars(select(LiftSegment).where(LiftSegment.id.in_(ids))))
    unknown = sorted(set(ids) - {s.id for s in segs})
    if unknown:
        invalid(["body", "segment_ids"], f"unknown segment ids {unknown[:20]}")
    wrong_study = [s.id for s in segs if _study_of_recording(db, s.recording_id) != study_id]
    if wrong_study:
        invalid(["body", "segment_ids"], f"segments {wrong_study[:20]} belong to another study")
    unlabelled = [s.id for s in segs if s.label not in MODEL_NAMES]
    if unlabelled:
        invalid(["body", "segment_ids"], f"segments {unlabelled[:20]} are not labelled as "
                f"{', '.join(MODEL_NAMES)}")
    counts = {m: sum(s.label == m for s in segs) for m in MODEL_NAMES}
    short = {m: c for m, c in counts.items() if c < 2}
    if short:
        invalid(["body", "segment_ids"], f"need at least 2 segments per motion, got {short}")
    params: dict[str, Any] = {"latent_dim": body.latent_dim,
                              "explained_variance": body.explained_variance, "counts": counts}
    row = ModelSetRecord(study_id=study_id, name=body.name, status="fitting", params=params,
                         segment_ids=ids, created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "model_set", row.id, {"name": body.name, **params})
    db.commit()
    plan = [(s.id, s.label, s.recording_id, s.start, s.end) for s in segs]
    engine = request.app.state.engine
    sessions: sessionmaker[Session] = request.app.state.sessions
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
        mset = fit_model_set(demos, q=body.latent_dim,
                             explained_variance=body.explained_variance,
                             version=f"study-{study_id}-modelset-{ms_id}", demo_ids=demo_ids,
                             meta={"study_id": study_id, "name": body.name})
        _set_row(sessions, ModelSetRecord, ms_id, document=mset.to_json(), status="ready")
        return f"fitted {sum(len(v) for v in demos.values())} demonstrations"

    job_id, _ = request.app.state.jobs.submit(
        "fit_model_set", ms_id, work, _failure(sessions, ModelSetRecord, ms_id))
    return ModelSetOut.model_validate(row).model_copy(update={"job_id": job_id})


@router.get("/api/studies/{study_id}/model-sets", response_model=list[ModelSetOut])
def list_model_sets(study_id: StudyId, user: CurrentUser, db: SessionDep
                    ) -> list[ModelSetRecord]:
    """The study's model sets, newest last."""
    one_or_404(db, Study, study_id, "study")
    return list(db.scalars(select(ModelSetRecord).where(ModelSetRecord.study_id == study_id)
                           .order_by(ModelSetRecord.id)))


@router.get("/api/model-sets/{model_set_id}", response_model=ModelSetOut)
def get_model_set(model_set_id: ModelSetId, user: CurrentUser, db: SessionDep
                  ) -> ModelSetRecord:
    """One model set's record."""
    return one_or_404(db, ModelSetRecord, model_set_id, "model set")


@router.get("/api/model-sets/{model_set_id}/document", response_model=dict[str, Any],
            responses=CONFLICT)
def model_set_document(model_set_id: ModelSetId, user: CurrentUser, db: SessionDep
                       ) -> dict[str, Any]:
    """The fitted model set as versioned JSON (the format `exostudy replay` reads)."""
    row = one_or_404(db, ModelSetRecord, model_set_id, "model set")
    if row.document is None:
        conflict("status", f"model set {row.id} is {row.status}")
    return row.document


def _submit_utilities(request: Request, db: Session, user: Any, study_id: int, name: str,
                      pct: float, human: HumanMotionData, source: str) -> UtilitySetOut:
    row = UtilitySetRecord(study_id=study_id, name=name, precompression_pct=pct,
                           human_source=source, status="computing",
                           human_data=human.to_json(), created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "utility_set", row.id,
                 {"name": name, "precompression_pct": pct, "human_source": source})
    db.commit()
    sessions: sessionmaker[Session] = request.app.state.sessions
    us_id = row.id

    def work(progress: Any) -> str:
        uset = compute_utilities(human, pct, progress=progress)
        _set_row(sessions, UtilitySetRecord, us_id, document=uset.to_json(), status="ready")
        return f"utilities for {pct:g} % precompression"

    job_id, _ = request.app.state.jobs.submit(
        "compute_utilities", us_id, work, _failure(sessions, UtilitySetRecord, us_id))
    return UtilitySetOut.model_validate(row).model_copy(update={"job_id": job_id})


@router.post("/api/studies/{study_id}/utility-sets", response_model=UtilitySetOut,
             status_code=202)
def compute_utility_set(study_id: StudyId, body: UtilitySetIn, request: Request,
                        user: CurrentUser, db: SessionDep) -> UtilitySetOut:
    """Compute utilities from the built-in simulated reference human dataset."""
    from controller.sim.human_dataset import reference_dataset

    one_or_404(db, Study, study_id, "study")
    human = reference_dataset()
    return _submit_utilities(request, db, user, study_id, body.name, body.precompression_pct,
                             human, f"simulated:{human.version}")


@router.post("/api/studies/{study_id}/utility-sets/import", response_model=UtilitySetOut,
             status_code=202, responses={422: {"description": "malformed CSV: row and column"}})
async def import_utility_set(
    study_id: StudyId, request: Request, user: CurrentUser, db: SessionDep,
    name: Annotated[str, Form(min_length=1, max_length=200)],
    precompression_pct: Annotated[float, Form(ge=0.0, le=100.0)],
    file: Annotated[UploadFile, File(description="CSV: motion,leg,n,theta_rad,tau_nm")],
) -> UtilitySetOut:
    """Compute utilities from a lab's own human motion data (CSV upload)."""
    one_or_404(db, Study, study_id, "study")
    raw = await file.read()
    if len(raw) > 5_000_000:
        invalid(["body", "file"], "file larger than 5 MB")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        invalid(["body", "file"], "not UTF-8 text")
    try:
        human = parse_human_data(text, source=f"imported:{file.filename or 'upload.csv'}")
    except CsvError as exc:
        invalid(["body", "file", f"row {exc.row}", exc.column], exc.problem)
    return _submit_utilities(request, db, user, study_id, name, precompression_pct, human,
                             human.source)


@router.get("/api/studies/{study_id}/utility-sets", response_model=list[UtilitySetOut])
def list_utility_sets(study_id: StudyId, user: CurrentUser, db: SessionDep
                      ) -> list[UtilitySetRecord]:
    """The study's utility sets."""
    one_or_404(db, Study, study_id, "study")
    return list(db.scalars(select(UtilitySetRecord)
                           .where(UtilitySetRecord.study_id == study_id)
                           .order_by(UtilitySetRecord.id)))


@router.get("/api/utility-sets/{utility_set_id}", response_model=UtilitySetOut)
def get_utility_set(utility_set_id: UtilitySetId, user: CurrentUser, db: SessionDep
                    ) -> UtilitySetRecord:
    """One utility set's record."""
    return one_or_404(db, UtilitySetRecord, utility_set_id, "utility set")


@router.get("/api/utility-sets/{utility_set_id}/document", response_model=dict[str, Any],
            responses=CONFLICT)
def utility_set_document(utility_set_id: UtilitySetId, user: CurrentUser, db: SessionDep
                         ) -> dict[str, Any]:
    """The utility set as versioned JSON (the format `exostudy replay` reads)."""
    row = one_or_404(db, UtilitySetRecord, utility_set_id, "utility set")
    if row.document is None:
        conflict("status", f"utility set {row.id} is {row.status}")
    return row.document


@router.get("/api/utility-sets/{utility_set_id}/curves", response_model=UtilityCurves,
            responses=CONFLICT)
def utility_curves(utility_set_id: UtilitySetId, user: CurrentUser, db: SessionDep
                   ) -> UtilityCurves:
    """Each action's utility minus "no lock", per motion, over progress."""
    row = one_or_404(db, UtilitySetRecord, utility_set_id, "utility set")
    if row.document is None:
        conflict("status", f"utility set {row.id} is {row.status}")
    v = UtilitySet.from_json(row.document).table.values
    diffs = {m: {ACTION_NAMES[a]: (v[a, j] - v[0, j]).tolist() for a in range(1, 4)}
             for j, m in enumerate(MODEL_NAMES)}
    other = {ACTION_NAMES[a]: float(v[a, 3, 0] - v[0, 3, 0]) for a in range(1, 4)}
    return UtilityCurves(progress=[n / 100 for n in range(v.shape[2])], differences=diffs,
                         other=other)


@router.get("/api/jobs/{job_id}", response_model=JobOut)
def get_job(job_id: JobId, user: CurrentUser, db: SessionDep) -> Job:
    """A background job's status and progress (0..1)."""
    db.expire_all()
    return one_or_404(db, Job, job_id, "job")



