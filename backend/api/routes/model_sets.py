"""Model sets and utility sets: fitted and computed as background jobs, with provenance."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, File, Form, Path, UploadFile

from backend.analysis import fitting, set_records
from backend.analysis.human_data_csv import CsvError, parse_human_data
from backend.api.deps import CurrentUser, EngineDep, JobsDep, SessionDep, SessionFactoryDep
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND, invalid, one_or_404
from backend.api.params import MAX_ID, StudyId
from backend.db.evidence_tables import Job, ModelSetRecord, UtilitySetRecord
from backend.db.models import Study
from backend.schemas.documents import ModelSetDocument, UtilitySetDocument
from backend.schemas.evidence import (
    JobOut,
    ModelSetIn,
    ModelSetOut,
    UtilityCurves,
    UtilitySetIn,
    UtilitySetOut,
)
from controller.decision.utility_function import UtilitySet
from controller.tick_record import ACTION_NAMES, MODEL_NAMES

router = APIRouter(tags=["models"], responses={**AUTH_RESPONSES, **NOT_FOUND})

ModelSetId = Annotated[int, Path(ge=1, le=MAX_ID, description="model set id")]
UtilitySetId = Annotated[int, Path(ge=1, le=MAX_ID, description="utility set id")]
JobId = Annotated[int, Path(ge=1, le=MAX_ID, description="job id")]


@router.post("/api/studies/{study_id}/model-sets", response_model=ModelSetOut,
             status_code=202, responses=CONFLICT)
def fit_models(study_id: StudyId, body: ModelSetIn, engine: EngineDep,
               sessions: SessionFactoryDep, jobs: JobsDep, user: CurrentUser,
               db: SessionDep) -> ModelSetOut:
    """Fit PPCA motion models from labelled segments of this study's recordings. Returns
    at once with the job id; poll `GET /api/jobs/{job_id}`."""
    one_or_404(db, Study, study_id, "study")
    return fitting.fit_model_set(db, engine, sessions, jobs, user, study_id, body)


@router.get("/api/studies/{study_id}/model-sets", response_model=list[ModelSetOut])
def list_model_sets(study_id: StudyId, user: CurrentUser, db: SessionDep
                    ) -> list[ModelSetRecord]:
    """The study's model sets, newest last."""
    return set_records.study_sets(db, ModelSetRecord, study_id)


@router.get("/api/model-sets/{model_set_id}", response_model=ModelSetOut)
def get_model_set(model_set_id: ModelSetId, user: CurrentUser, db: SessionDep
                  ) -> ModelSetRecord:
    """One model set's record."""
    return set_records.one_set(db, ModelSetRecord, model_set_id)


@router.get("/api/model-sets/{model_set_id}/document", response_model=ModelSetDocument,
            response_model_exclude_unset=True,
            responses=CONFLICT)
def model_set_document(model_set_id: ModelSetId, user: CurrentUser, db: SessionDep
                       ) -> dict[str, Any]:
    """The fitted model set as versioned JSON (the format `exostudy replay` reads)."""
    return set_records.ready_document(db, ModelSetRecord, model_set_id)


@router.post("/api/studies/{study_id}/utility-sets", response_model=UtilitySetOut,
             status_code=202)
def compute_utility_set(study_id: StudyId, body: UtilitySetIn, jobs: JobsDep,
                        sessions: SessionFactoryDep,
                        user: CurrentUser, db: SessionDep) -> UtilitySetOut:
    """Compute utilities from the built-in simulated reference human dataset."""
    from controller.sim.human_dataset import reference_dataset

    one_or_404(db, Study, study_id, "study")
    human = reference_dataset()
    return fitting.compute_utility_set(jobs, sessions, db, user, study_id, body.name,
                                       body.precompression_pct, human,
                                       f"simulated:{human.version}")


@router.post("/api/studies/{study_id}/utility-sets/import", response_model=UtilitySetOut,
             status_code=202, responses={422: {"description": "malformed CSV: row and column"}})
async def import_utility_set(
    study_id: StudyId, jobs: JobsDep, sessions: SessionFactoryDep, user: CurrentUser,
    db: SessionDep, name: Annotated[str, Form(min_length=1, max_length=200)],
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
    return fitting.compute_utility_set(jobs, sessions, db, user, study_id, name,
                                       precompression_pct, human, human.source)


@router.get("/api/studies/{study_id}/utility-sets", response_model=list[UtilitySetOut])
def list_utility_sets(study_id: StudyId, user: CurrentUser, db: SessionDep
                      ) -> list[UtilitySetRecord]:
    """The study's utility sets."""
    return set_records.study_sets(db, UtilitySetRecord, study_id)


@router.get("/api/utility-sets/{utility_set_id}", response_model=UtilitySetOut)
def get_utility_set(utility_set_id: UtilitySetId, user: CurrentUser, db: SessionDep
                    ) -> UtilitySetRecord:
    """One utility set's record."""
    return set_records.one_set(db, UtilitySetRecord, utility_set_id)


@router.get("/api/utility-sets/{utility_set_id}/document", response_model=UtilitySetDocument,
            response_model_exclude_unset=True,
            responses=CONFLICT)
def utility_set_document(utility_set_id: UtilitySetId, user: CurrentUser, db: SessionDep
                         ) -> dict[str, Any]:
    """The utility set as versioned JSON (the format `exostudy replay` reads)."""
    return set_records.ready_document(db, UtilitySetRecord, utility_set_id)


@router.get("/api/utility-sets/{utility_set_id}/curves", response_model=UtilityCurves,
            responses=CONFLICT)
def utility_curves(utility_set_id: UtilitySetId, user: CurrentUser, db: SessionDep
                   ) -> UtilityCurves:
    """Each action's utility minus "no lock", per motion, over progress."""
    v = UtilitySet.from_json(set_records.ready_document(db, UtilitySetRecord,
                                                        utility_set_id)).table.values
    diffs = {m: {ACTION_NAMES[a]: (v[a, j] - v[0, j]).tolist() for a in range(1, 4)}
             for j, m in enumerate(MODEL_NAMES)}
    other = {ACTION_NAMES[a]: float(v[a, 3, 0] - v[0, 3, 0]) for a in range(1, 4)}
    return UtilityCurves(progress=[n / 100 for n in range(v.shape[2])], differences=diffs,
                         other=other)


@router.get("/api/jobs/{job_id}", response_model=JobOut)
def get_job(job_id: JobId, user: CurrentUser, db: SessionDep) -> Job:
    """A background job's status, progress (0..1) and message: a model fit or utility
    table (the viewer role in its study) or a virtual cohort (which belongs to no study:
    the viewer role in some study). `done`, `failed` and `cancelled` are final."""
    db.expire_all()
    return one_or_404(db, Job, job_id, "job")



