"""The replication report from the console: start one as a background job, read the
newest one (its claims as JSON, the self-contained HTML page, its figures).

Like virtual cohorts, a replication involves no participant data: any logged-in
account may run and read it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, HTTPException, Response
from fastapi import Path as PathParam
from fastapi.responses import FileResponse, HTMLResponse

from backend.analysis import replication_jobs
from backend.api.deps import CurrentUser, JobsDep, SessionDep, SettingsDep, access
from backend.api.errors import AUTH_RESPONSES, CONFLICT, NOT_FOUND, ErrorMessage
from backend.schemas.replication import (
    ReplicationIn,
    ReplicationJobOut,
    ReplicationReportOut,
    ReplicationStarted,
    ReplicationStateOut,
)

router = APIRouter(tags=["replication"], responses={**AUTH_RESPONSES, **NOT_FOUND})

FigureName = Annotated[str, PathParam(pattern=r"^[a-z_]{1,40}$",
                                      description="figure name, e.g. peak_torques")]


@router.post("/api/replication", status_code=202, response_model=ReplicationStarted,
             openapi_extra=access("login"), responses=CONFLICT)
def start_replication(body: ReplicationIn, jobs: JobsDep, user: CurrentUser,
                      settings: SettingsDep) -> ReplicationStarted:
    """Run the replication report in the background (the `cohort` engine); poll
    `GET /api/replication` for its progress, then its claims. 409 while the account
    already has `replication_jobs_per_account` reports queued or running."""
    job_id, folder = replication_jobs.start(jobs, user, settings.run_dir, body.seeds,
                                            body.participants,
                                            settings.replication_jobs_per_account)
    return ReplicationStarted(job_id=job_id, folder=folder.name)


@router.get("/api/replication", response_model=ReplicationStateOut,
            openapi_extra=access("login"))
def latest(user: CurrentUser, db: SessionDep, settings: SettingsDep) -> ReplicationStateOut:
    """The newest replication job (status, progress, message) and the newest finished
    report's claims; either is null when there is none."""
    db.expire_all()
    job = replication_jobs.latest_job(db)
    folder = replication_jobs.latest_report(settings.run_dir)
    return ReplicationStateOut(
        job=None if job is None else ReplicationJobOut(id=job.id, status=job.status,
                                                       progress=job.progress,
                                                       message=job.message),
        report=None if folder is None else ReplicationReportOut.model_validate(
            replication_jobs.summary(folder)),
    )


def _folder(settings: Any) -> Path:
    folder = replication_jobs.latest_report(settings.run_dir)
    if folder is None:
        raise HTTPException(404, "report: there is no replication report yet; "
                            "POST /api/replication starts one")
    return folder


@router.get("/api/replication/report", response_class=HTMLResponse,
            openapi_extra=access("login"),
            responses={404: {"description": "no report yet",
                              "content": {"application/json": {
                                  "schema": ErrorMessage.model_json_schema()}}}})
def report_page(user: CurrentUser, settings: SettingsDep) -> Response:
    """The newest report as its self-contained HTML page."""
    return HTMLResponse((_folder(settings) / "report.html").read_text())


@router.get("/api/replication/figures/{name}.{fmt}", openapi_extra=access("login"),
            response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/svg+xml": {}}},
                       404: {"model": ErrorMessage, "description": "no report or figure"}})
def figure(name: FigureName, fmt: Literal["png", "svg"], user: CurrentUser,
           settings: SettingsDep) -> Response:
    """One figure of the newest report."""
    path = _folder(settings) / "figures" / f"{name}.{fmt}"
    if not path.is_file():
        raise HTTPException(404, f"figure: the newest report has no figure {name}.{fmt}")
    return FileResponse(path, media_type="image/png" if fmt == "png" else "image/svg+xml")
