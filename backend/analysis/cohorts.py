"""Virtual cohorts run from the console: recorded, then simulated and analysed as a
background job (the cohort lane, in a child process) with the server's default model
and utility sets. Each account may have a few unfinished at a time.

The service behind `backend/api/routes/cohorts.py`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy import select, update
from sqlalchemy.orm import Session, sessionmaker

from backend.analysis.job_process import run_in_child
from backend.analysis.jobs import JobRunner, QuotaFullError, Reporter
from backend.core.errors import ConflictError, NotFoundError
from backend.db import audit
from backend.db.cohorts import CohortRecord
from backend.db.evidence_tables import Job
from backend.db.models import User
from backend.schemas.cohorts import CohortIn, CohortOut

if TYPE_CHECKING:
    from controller.evaluation.cohort import CohortConfig


def _set(sessions: sessionmaker[Session], cohort_id: int, **values: Any) -> None:
    with sessions() as s:
        s.execute(update(CohortRecord).where(CohortRecord.id == cohort_id).values(**values))
        s.commit()


def compute(cfg: CohortConfig, models_path: Path, utilities_path: Path,
            progress: Callable[[float], None]) -> dict[str, Any]:
    """Simulate and analyse the cohort: its cohort.json document. Runs in the job's
    child process (`backend.analysis.job_process`), so it takes only picklable values."""
    # Deferred: the simulator and its compiled kernels load in the job's child process
    # only, so the server (which imports this module) starts without them.
    from controller.decision.utility_function import UtilitySet
    from controller.evaluation.cohort import simulate_cohort
    from controller.evaluation.cohort_report import analyse, analysis_json
    from controller.intent.motion_model import ModelSet

    models = ModelSet.load(models_path) if models_path.is_file() else None
    utilities = UtilitySet.load(utilities_path) if utilities_path.is_file() else None
    cohort = simulate_cohort(cfg, models, utilities, lambda f: progress(0.85 * f))
    doc: dict[str, Any] = analysis_json(cohort, analyse(cohort, seed=cfg.seed))
    return doc


def start_cohort(db: Session, sessions: sessionmaker[Session], jobs: JobRunner, user: User,
                 body: CohortIn, precompression_pct: float, models_path: Path,
                 utilities_path: Path, per_account: int) -> CohortOut:
    """Record the cohort as `queued` and queue its simulation and analysis in the
    cohort lane; the answer carries the job id. Refused (409, `ConflictError`) beyond
    `per_account` unfinished cohorts of this account."""
    # The job first: it takes one of the account's slots or is refused, before anything
    # is recorded (one unique index decides, however many requests arrive together).
    try:
        job_id = jobs.reserve("cohort", lane="cohort", owner_id=user.id, quota=per_account)
    except QuotaFullError as exc:
        raise ConflictError("cohorts", f"account {user.username} already has "
                            f"{len(exc.unfinished)} unfinished virtual cohort(s) (jobs "
                            f"{exc.unfinished}); at most {per_account} may be queued or "
                            "running per account (setting cohort_jobs_per_account): wait "
                            "for one to finish") from None
    # Deferred as in `compute`: the cohort engine imports the simulator.
    from controller.evaluation.cohort import CohortConfig

    cfg = CohortConfig(participants=body.participants, seed=body.seed,
                       controllers=tuple(body.controllers), rate_hz=body.rate_hz,
                       precompression_pct=precompression_pct)
    row = CohortRecord(name=body.name or f"{body.participants} virtual participants, seed "
                       f"{body.seed}", config=body.model_dump(), status="queued",
                       created_by=user.id)
    try:
        db.add(row)
        db.flush()
        audit.record(db, user, "create", "cohort", row.id, body.model_dump())
        db.commit()
    except BaseException:
        db.rollback()
        jobs.abandon(job_id, "cancelled: the cohort could not be recorded")
        raise
    cohort_id = row.id

    def work(progress: Reporter) -> str:
        t0 = time.monotonic()
        _set(sessions, cohort_id, status="running")
        doc = run_in_child(compute, (cfg, models_path, utilities_path), progress,
                           progress.cancelled)
        progress(1.0)
        wall = round(time.monotonic() - t0, 1)
        _set(sessions, cohort_id, status="ready", result=doc, wall_s=wall,
             finished_at=datetime.now(UTC))
        return f"{cfg.participants} virtual participants in {wall:.0f} s"

    def failed(message: str) -> None:
        _set(sessions, cohort_id, status="failed", error=message[:2000],
             finished_at=datetime.now(UTC))

    jobs.enqueue(job_id, work, failed, target_id=cohort_id)
    return CohortOut.model_validate(row).model_copy(update={"job_id": job_id})


def newest_first(db: Session) -> list[CohortRecord]:
    """Every cohort, the newest first."""
    return list(db.scalars(select(CohortRecord).order_by(CohortRecord.id.desc())))


def current(db: Session, cohort_id: int) -> CohortRecord:
    """The cohort as its job last wrote it (the job writes from its own session, so
    what this session loaded before is stale); `NotFoundError` if there is none."""
    db.expire_all()
    row = db.get(CohortRecord, cohort_id)
    if row is None:
        raise NotFoundError("cohort", cohort_id)
    return row


def progress(db: Session, cohort_id: int) -> dict[str, Any]:
    """`job_id` and `progress` of the cohort's latest job ({} if it has none)."""
    job = db.scalars(select(Job).where(Job.kind == "cohort", Job.target_id == cohort_id)
                     .order_by(Job.id.desc())).first()
    return {} if job is None else {"job_id": job.id, "progress": job.progress}
