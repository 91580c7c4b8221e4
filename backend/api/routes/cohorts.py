"""Virtual cohorts from the console: run one as a background job, read its analysis,
tables and figures.

A cohort is a planning tool outside any study (no participant data is involved), so any
logged-in account may run and read cohorts. The job uses the server's default model
set and utility set, the ones the live controllers use.
"""

from __future__ import annotations

import time
from datetime import UTC, datetime
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Request, Response
from fastapi import Path as PathParam
from pydantic import BaseModel, ConfigDict, Field, field_validator
from sqlalchemy import select, update
from sqlalchemy.orm import Session, sessionmaker

from backend import audit
from backend.api.deps import CurrentUser, RuntimeDep, SessionDep, access
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND, conflict, one_or_404
from backend.api.params import MAX_ID
from backend.db.cohorts import CohortRecord
from controller.evaluation.cohort import COHORT_CONTROLLERS, CohortConfig

router = APIRouter(tags=["cohorts"], responses={**AUTH_RESPONSES, **NOT_FOUND})

CohortId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="cohort id")]
#: A console cohort runs on the server's job thread: bounded so one request cannot hold
#: it for long (1,000 participants take a few minutes; the CLI has no such limit).
MAX_API_PARTICIPANTS = 1000
TABLES = ("participants", "metrics", "comparisons", "power")
FIGURES = ("power", "distributions")


class CohortIn(BaseModel):
    """What to simulate."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(default="", max_length=200)
    participants: int = Field(default=100, ge=2, le=MAX_API_PARTICIPANTS)
    seed: int = Field(default=1, ge=0, le=99_999)
    controllers: list[str] = Field(default_factory=lambda: list(COHORT_CONTROLLERS),
                                   min_length=1, max_length=3)
    rate_hz: float | None = Field(default=None, ge=1.0, le=100.0, description=(
        "every controller at this rate; null: the paper's rates"))

    @field_validator("controllers")
    @classmethod
    def _known(cls, v: list[str]) -> list[str]:
        unknown = [c for c in v if c not in COHORT_CONTROLLERS]
        if unknown:
            raise ValueError(f"unknown controller(s) {unknown}; choose from "
                             f"{', '.join(COHORT_CONTROLLERS)}")
        if len(set(v)) != len(v):
            raise ValueError("each controller once")
        return v


class CohortOut(BaseModel):
    """A cohort's record; `result` (the cohort.json document) once it is ready."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    name: str
    config: dict[str, Any]
    status: str
    error: str
    wall_s: float | None
    created_at: datetime
    finished_at: datetime | None
    job_id: int | None = None
    #: The job's progress, 0..1 (a cohort belongs to no study, so its job is followed
    #: here rather than through `/api/jobs`, whose access is per study).
    progress: float | None = None
    result: dict[str, Any] | None = None


def _set(sessions: sessionmaker[Session], cohort_id: int, **values: Any) -> None:
    with sessions() as s:
        s.execute(update(CohortRecord).where(CohortRecord.id == cohort_id).values(**values))
        s.commit()


@router.post("/api/cohorts", response_model=CohortOut, status_code=202,
             openapi_extra=access("login"))
def start_cohort(body: CohortIn, request: Request, user: CurrentUser, db: SessionDep,
                 runtime: RuntimeDep) -> CohortOut:
    """Simulate a virtual cohort in the background; poll `GET /api/cohorts/{id}` for
    its progress, then its analysis."""
    from controller.evaluation.cohort import simulate_cohort
    from controller.evaluation.cohort_report import analyse, analysis_json
    from controller.motion_model import ModelSet
    from controller.utilities import UtilitySet

    cfg = CohortConfig(participants=body.participants, seed=body.seed,
                       controllers=tuple(body.controllers), rate_hz=body.rate_hz,
                       precompression_pct=runtime.settings.precompression_pct)
    row = CohortRecord(name=body.name or f"{body.participants} virtual participants, seed "
                       f"{body.seed}", config=body.model_dump(), status="queued",
                       created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "cohort", row.id, body.model_dump())
    db.commit()
    sessions: sessionmaker[Session] = request.app.state.sessions
    cohort_id = row.id
    models_path, utilities_path = runtime.settings.models_path, runtime.utilities_path()

    def work(progress: Any) -> str:
        t0 = time.monotonic()
        _set(sessions, cohort_id, status="running")
        models = ModelSet.load(models_path) if models_path.is_file() else None
        utilities = UtilitySet.load(utilities_path) if utilities_path.is_file() else None
        cohort = simulate_cohort(cfg, models, utilities, lambda f: progress(0.85 * f))
        doc = analysis_json(cohort, analyse(cohort, seed=cfg.seed))
        progress(1.0)
        wall = round(time.monotonic() - t0, 1)
        _set(sessions, cohort_id, status="ready", result=doc, wall_s=wall,
             finished_at=datetime.now(UTC))
        return f"{cfg.participants} virtual participants in {wall:.0f} s"

    def failed(message: str) -> None:
        _set(sessions, cohort_id, status="failed", error=message[:2000],
             finished_at=datetime.now(UTC))

    job_id, _ = request.app.state.jobs.submit("cohort", cohort_id, work, failed)
    return CohortOut.model_validate(row).model_copy(update={"job_id": job_id})


@router.get("/api/cohorts", response_model=list[CohortOut], openapi_extra=access("login"))
def list_cohorts(user: CurrentUser, db: SessionDep) -> list[CohortOut]:
    """Every cohort, newest first, without their results."""
    rows = db.scalars(select(CohortRecord).order_by(CohortRecord.id.desc()))
    return [CohortOut.model_validate(r).model_copy(update={"result": None}) for r in rows]


def _job(db: Session, cohort_id: int) -> dict[str, Any]:
    from backend.db.evidence import Job

    job = db.scalars(select(Job).where(Job.kind == "cohort", Job.target_id == cohort_id)
                     .order_by(Job.id.desc())).first()
    return {} if job is None else {"job_id": job.id, "progress": job.progress}


@router.get("/api/cohorts/{cohort_id}", response_model=CohortOut,
            openapi_extra=access("login"))
def get_cohort(cohort_id: CohortId, user: CurrentUser, db: SessionDep) -> CohortOut:
    """One cohort with its analysis (`result`, the cohort.json document) once ready."""
    db.expire_all()
    row = one_or_404(db, CohortRecord, cohort_id, "cohort")
    return CohortOut.model_validate(row).model_copy(update=_job(db, row.id))


def _ready(db: Session, cohort_id: int) -> dict[str, Any]:
    row = one_or_404(db, CohortRecord, cohort_id, "cohort")
    if row.status != "ready" or row.result is None:
        conflict("status", f"cohort {row.id} is {row.status}"
                 + (f": {row.error}" if row.error else ""))
    return row.result


@router.get("/api/cohorts/{cohort_id}/tables/{name}.{fmt}", openapi_extra=access("login"),
            responses={**CONFLICT, 200: {"content": {"text/csv": {}, "text/markdown": {}}}})
def cohort_table(cohort_id: CohortId, name: Literal["participants", "metrics",
                                                    "comparisons", "power"],
                 fmt: Literal["csv", "md"], user: CurrentUser, db: SessionDep) -> Response:
    """A table of a ready cohort, as CSV or Markdown."""
    from controller.evaluation import cohort_report as rep

    cohort, analysis = rep.from_json(_ready(db, cohort_id))
    table = {"participants": lambda: rep.participants_table(cohort),
             "metrics": lambda: rep.summary_table(analysis),
             "comparisons": lambda: rep.comparisons_table(analysis),
             "power": lambda: rep.power_table(analysis)}[name]()
    if fmt == "csv":
        return Response(table.to_csv(), media_type="text/csv")
    return Response(table.to_markdown(), media_type="text/markdown")


@router.get("/api/cohorts/{cohort_id}/figures/{name}.{fmt}", openapi_extra=access("login"),
            responses={**CONFLICT, 200: {"content": {"image/png": {}, "image/svg+xml": {}}}})
def cohort_figure(cohort_id: CohortId, name: Literal["power", "distributions"],
                  fmt: Literal["png", "svg"], user: CurrentUser, db: SessionDep) -> Response:
    """A figure of a ready cohort: power curves or metric distributions."""
    from controller.evaluation import cohort_report as rep

    cohort, analysis = rep.from_json(_ready(db, cohort_id))
    png, svg = rep.figures(cohort, analysis)[name]
    return Response(png if fmt == "png" else svg,
                    media_type="image/png" if fmt == "png" else "image/svg+xml")
