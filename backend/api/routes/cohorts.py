"""Virtual cohorts from the console: run one as a background job, read its analysis,
tables and figures.

A cohort is a planning tool outside any study (no participant data is involved), so any
logged-in account may read cohorts; running one takes minutes of the server's CPU, so
it needs the experimenter role in some study, and each account may have only a few
queued or running (`cohort_jobs_per_account`). The job uses the server's default model
set and utility set, the ones the live controllers use.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Response
from fastapi import Path as PathParam
from sqlalchemy.orm import Session

from backend.analysis import cohorts
from backend.api.deps import (
    CurrentUser,
    JobsDep,
    RuntimeDep,
    SessionDep,
    SessionFactoryDep,
    access,
)
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND, conflict, one_or_404
from backend.api.params import MAX_ID
from backend.db.cohorts import CohortRecord
from backend.schemas.cohorts import CohortIn, CohortOut

router = APIRouter(tags=["cohorts"], responses={**AUTH_RESPONSES, **NOT_FOUND})

CohortId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="cohort id")]
TABLES = ("participants", "metrics", "comparisons", "power")


@router.post("/api/cohorts", response_model=CohortOut, status_code=202,
             openapi_extra=access("experimenter"), responses=CONFLICT)
def start_cohort(body: CohortIn, sessions: SessionFactoryDep, jobs: JobsDep,
                 user: CurrentUser, db: SessionDep, runtime: RuntimeDep) -> CohortOut:
    """Simulate a virtual cohort in the background; poll `GET /api/cohorts/{id}` (or
    `GET /api/jobs/{job_id}`) for its progress, then its analysis. Needs the
    experimenter role in some study (it takes minutes of the server's CPU); 409 while
    the account already has `cohort_jobs_per_account` cohorts queued or running."""
    settings = runtime.settings
    return cohorts.start_cohort(db, sessions, jobs, user, body,
                                settings.precompression_pct, settings.models_path,
                                runtime.utilities_path(), settings.cohort_jobs_per_account)


@router.get("/api/cohorts", response_model=list[CohortOut], openapi_extra=access("login"))
def list_cohorts(user: CurrentUser, db: SessionDep) -> list[CohortOut]:
    """Every cohort, newest first, without their results."""
    rows = cohorts.newest_first(db)
    return [CohortOut.model_validate(r).model_copy(update={"result": None}) for r in rows]


@router.get("/api/cohorts/{cohort_id}", response_model=CohortOut,
            openapi_extra=access("login"))
def get_cohort(cohort_id: CohortId, user: CurrentUser, db: SessionDep) -> CohortOut:
    """One cohort with its analysis (`result`, the cohort.json document) once ready."""
    row = cohorts.current(db, cohort_id)
    return CohortOut.model_validate(row).model_copy(update=cohorts.progress(db, row.id))


def _ready(db: Session, cohort_id: int) -> dict[str, Any]:
    row = one_or_404(db, CohortRecord, cohort_id, "cohort")
    if row.status != "ready" or row.result is None:
        conflict("status", f"cohort {row.id} is {row.status}"
                 + (f": {row.error}" if row.error else ""))
    return row.result


@router.get("/api/cohorts/{cohort_id}/tables/{name}.{fmt}", openapi_extra=access("login"),
            response_class=Response,
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
            response_class=Response,
            responses={**CONFLICT, 200: {"content": {"image/png": {}, "image/svg+xml": {}}}})
def cohort_figure(cohort_id: CohortId, name: Literal["power", "distributions"],
                  fmt: Literal["png", "svg"], user: CurrentUser, db: SessionDep) -> Response:
    """A figure of a ready cohort: power curves or metric distributions."""
    from controller.evaluation import cohort_report as rep

    cohort, analysis = rep.from_json(_ready(db, cohort_id))
    png, svg = rep.figures(cohort, analysis)[name]
    return Response(png if fmt == "png" else svg,
                    media_type="image/png" if fmt == "png" else "image/svg+xml")
