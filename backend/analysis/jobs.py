"""Background computations (fitting models, computing utilities) with progress in the
database, so the console can poll `GET /api/jobs/{id}` and a restart shows what failed.

One worker thread: these jobs are CPU-bound and the control loop must keep its core.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from datetime import UTC, datetime

from sqlalchemy import update
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, sessionmaker

from backend.db.evidence_tables import Job

log = logging.getLogger(__name__)

#: Tries for a job's status change while SQLite reports "database is locked".
STATUS_ATTEMPTS = 4

Progress = Callable[[float], None]
Work = Callable[[Progress], str]


class JobRunner:
    """Runs jobs one at a time and records their status, progress and message."""

    def __init__(self, sessions: sessionmaker[Session]) -> None:
        self.sessions = sessions
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="job")

    def submit(self, kind: str, target_id: int, work: Work,
               on_failure: Callable[[str], None] | None = None) -> tuple[int, Future[None]]:
        """Queue `work(progress) -> message`; returns the job id and its future."""
        with self.sessions() as db:
            job = Job(kind=kind, target_id=target_id, status="queued", progress=0.0)
            db.add(job)
            db.commit()
            job_id = job.id
        return job_id, self.pool.submit(self._run, job_id, work, on_failure)

    def _set(self, job_id: int, **values: object) -> None:
        with self.sessions() as db:
            db.execute(update(Job).where(Job.id == job_id).values(**values))
            db.commit()

    def _set_status(self, job_id: int, **values: object) -> None:
        """A status change must be stored, or a poller waits for ever: retried while
        the database is busy beyond its timeout (a few times, then it raises)."""
        for attempt in range(STATUS_ATTEMPTS):
            try:
                self._set(job_id, **values)
                return
            except OperationalError:
                if attempt == STATUS_ATTEMPTS - 1:
                    raise
                time.sleep(1.0 + attempt)

    def _run(self, job_id: int, work: Work, on_failure: Callable[[str], None] | None) -> None:
        self._set_status(job_id, status="running")
        last = [0.0]

        def progress(fraction: float) -> None:
            now = time.monotonic()
            if now - last[0] > 0.2 or fraction >= 1.0:  # at most 5 writes a second
                last[0] = now
                try:
                    self._set(job_id, progress=max(0.0, min(1.0, float(fraction))))
                except OperationalError as exc:
                    # Progress is for the eye: a database busy beyond its timeout (a
                    # loaded machine storing ticks) must not fail the computation.
                    log.warning("job %s: progress not stored (%s)", job_id, exc.orig)

        try:
            message = work(progress)
        except Exception as exc:
            log.exception("job %s failed", job_id)
            msg = f"{type(exc).__name__}: {exc}"
            if on_failure is not None:
                on_failure(msg)
            self._set_status(job_id, status="failed", message=msg[:2000],
                      finished_at=datetime.now(UTC))
            return
        self._set_status(job_id, status="done", progress=1.0, message=message,
                  finished_at=datetime.now(UTC))

    def shutdown(self) -> None:
        """Finish the running job, drop the queued ones."""
        self.pool.shutdown(wait=True, cancel_futures=True)
