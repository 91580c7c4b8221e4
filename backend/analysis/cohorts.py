"""Virtual cohorts run from the console: recorded, then simulated and analysed on the
background job thread with the server's default model and utility sets.

The service behind `backend/api/routes/cohorts.py`.
"""

from __future__ import annotations

import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import update
from sqlalchemy.orm import Session, sessionmaker

from backend.analysis.jobs import JobRunner
from backend.db.cohorts import CohortRecord
from backend.db.models import User
from backend.schemas.cohorts import CohortIn, CohortOut
from backend.study import audit
from controller.evaluation.cohort import CohortConfig


def _set(sessions: sessionmaker[Session], cohort_id: int, **values: Any) -> None:
    with sessions() as s:
        s.execute(update(CohortRecord).where(CohortRecord.id == cohort_id).values(**values))
        s.commit()


def start_cohort(db: Session, sessions: sessionmaker[Session], jobs: JobRunner, user: User,
                 body: CohortIn, precompression_pct: float, models_path: Path,
                 utilities_path: Path) -> CohortOut:
    """Record the cohort as `queued` and queue its simulation and analysis; the answer
    carries the job id."""
    from controller.evaluation.cohort import simulate_cohort
    from controller.evaluation.cohort_report import analyse, analysis_json
    from controller.motion_model import ModelSet
    from controller.utilities import UtilitySet

    cfg = CohortConfig(participants=body.participants, seed=body.seed,
                       controllers=tuple(body.controllers), rate_hz=body.rate_hz,
                       precompression_pct=precompression_pct)
    row = CohortRecord(name=body.name or f"{body.participants} virtual participants, seed "
                       f"{body.seed}", config=body.model_dump(), status="queued",
                       created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "cohort", row.id, body.model_dump())
    db.commit()
    cohort_id = row.id

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

    job_id, _ = jobs.submit("cohort", cohort_id, work, failed)
    return CohortOut.model_validate(row).model_copy(update={"job_id": job_id})
