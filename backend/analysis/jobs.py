"""Background computations (fitting models, computing utilities, virtual cohorts) with
their state in the database, so the console can poll `GET /api/jobs/{id}` and a restart
or a shutdown leaves every job and what it was producing in a final state with a reason.

A job is `queued`, `running`, then `done` (it succeeded; the name clients have always
polled for), `failed` or `cancelled`. Two lanes, each one thread taking its jobs one at
a time: `study` for the short study jobs (a model fit, a utility table) and `cohort` for
virtual cohorts, which take minutes, so a fit never waits behind cohorts. Within a lane
the accounts take turns (round robin), so one account's queue does not hold up another's.
Work is cancelled cooperatively: its progress callback raises `JobCancelledError` once the
job is cancelled (cohorts run in a child process, which is terminated instead).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from datetime import UTC, datetime

from sqlalchemy import select, update
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, sessionmaker

from backend.core.errors import ConflictError
from backend.db.cohorts import CohortRecord
from backend.db.evidence_tables import Job, ModelSetRecord, UtilitySetRecord

log = logging.getLogger(__name__)

#: Tries for a job's status change while SQLite reports "database is locked".
STATUS_ATTEMPTS = 4
#: Every state a job can be in; the last three are final.
JOB_STATES = ("queued", "running", "done", "failed", "cancelled")
UNFINISHED = ("queued", "running")
#: The lanes, each its own thread.
LANES = ("study", "cohort")
#: How long a shutdown waits for each lane's running job to notice its cancellation.
SHUTDOWN_WAIT_S = 10.0

Progress = Callable[[float], None]


class Reporter:
    """What a job's work gets: call it with the fraction done (it raises `JobCancelledError`
    once the job is cancelled); `cancelled` is the event itself, for work that waits
    on something else (a child process)."""

    def __init__(self, report: Progress, cancelled: threading.Event) -> None:
        self._report = report
        self.cancelled = cancelled

    def __call__(self, fraction: float) -> None:
        self._report(fraction)


Work = Callable[[Reporter], str]


class JobCancelledError(Exception):
    """Raised inside a job's work once the job is cancelled (by its progress callback,
    or by the child-process runner); the job ends `cancelled` with the reason."""


def now_text() -> str:
    """The current UTC time as it appears in reasons (to the second)."""
    return datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


@dataclass
class _Entry:
    """A submitted job as its lane holds it."""

    job_id: int
    work: Work
    on_failure: Callable[[str], None] | None
    owner: int | None
    future: Future[None] = field(default_factory=Future)
    cancel: threading.Event = field(default_factory=threading.Event)
    reason: str = ""


class _Lane:
    """One thread running its jobs one at a time, the accounts taking turns."""

    def __init__(self, name: str, run: Callable[[_Entry], None]) -> None:
        self.name = name
        self._run = run
        self._cond = threading.Condition()
        # Insertion-ordered: the front account goes next, then moves to the back.
        self._queues: dict[int | None, deque[_Entry]] = {}
        self._closed = False
        self.current: _Entry | None = None
        self._thread = threading.Thread(target=self._loop, name=f"job-{name}", daemon=True)
        self._thread.start()

    def put(self, entry: _Entry) -> None:
        with self._cond:
            if self._closed:
                raise ConflictError("server", "the server is shutting down: no new jobs")
            self._queues.setdefault(entry.owner, deque()).append(entry)
            self._cond.notify()

    def _next(self) -> _Entry | None:
        with self._cond:
            while not self._queues and not self._closed:
                self._cond.wait()
            if self._closed:
                return None
            owner = next(iter(self._queues))
            queue = self._queues.pop(owner)
            entry = queue.popleft()
            if queue:
                self._queues[owner] = queue  # back of the line: the next account's turn
            self.current = entry
            return entry

    def _loop(self) -> None:
        while (entry := self._next()) is not None:
            try:
                self._run(entry)
            except Exception:  # the lane must outlive any one job's bookkeeping
                log.exception("job %s: lane %s", entry.job_id, self.name)
            finally:
                if not entry.future.done():
                    entry.future.set_result(None)
                with self._cond:
                    self.current = None

    def close(self, reason: str) -> list[_Entry]:
        """Take no more jobs; cancel the running one; return the queued ones."""
        with self._cond:
            self._closed = True
            dropped = [e for q in self._queues.values() for e in q]
            self._queues.clear()
            if self.current is not None:
                self.current.reason = reason
                self.current.cancel.set()
            self._cond.notify_all()
        return dropped

    def join(self, timeout: float) -> bool:
        self._thread.join(timeout)
        return not self._thread.is_alive()


class JobRunner:
    """Runs jobs in their lanes and records their status, progress and message."""

    def __init__(self, sessions: sessionmaker[Session]) -> None:
        self.sessions = sessions
        self._entries: dict[int, _Entry] = {}
        self._closing = False
        self._lanes = {name: _Lane(name, self._run) for name in LANES}

    def submit(self, kind: str, target_id: int, work: Work,
               on_failure: Callable[[str], None] | None = None, *, lane: str = "study",
               owner_id: int | None = None) -> tuple[int, Future[None]]:
        """Queue `work(progress) -> message` in `lane`; returns the job id and a future
        that completes when the job has ended, however it ended. `on_failure(reason)`
        is called when the job fails or is cancelled, to leave its product final.
        Refused (`ConflictError`, a 409) once the server is shutting down."""
        if lane not in self._lanes:
            raise ValueError(f"unknown job lane {lane!r}; choose from {', '.join(LANES)}")
        with self.sessions() as db:
            job = Job(kind=kind, target_id=target_id, status="queued", progress=0.0,
                      lane=lane, created_by=owner_id)
            db.add(job)
            db.commit()
            job_id = job.id
        entry = _Entry(job_id, work, on_failure, owner_id)
        self._entries[job_id] = entry
        try:
            self._lanes[lane].put(entry)
        except ConflictError:
            self._end(entry, "cancelled", "the server is shutting down: not started")
            raise
        return job_id, entry.future

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

    def _end(self, entry: _Entry, status: str, reason: str) -> None:
        """A failed or cancelled job: its product first (so a poller that sees the job
        final finds the product final too), then the job."""
        try:
            if entry.on_failure is not None:
                entry.on_failure(reason)
        finally:
            self._set_status(entry.job_id, status=status, message=reason[:2000],
                             finished_at=datetime.now(UTC))
            self._entries.pop(entry.job_id, None)
            if not entry.future.done():
                entry.future.set_result(None)

    def _run(self, entry: _Entry) -> None:
        job_id = entry.job_id
        if entry.cancel.is_set():
            self._end(entry, "cancelled", entry.reason or "cancelled before it started")
            return
        self._set_status(job_id, status="running", started_at=datetime.now(UTC))
        last = [0.0]

        def progress(fraction: float) -> None:
            if entry.cancel.is_set():
                raise JobCancelledError(entry.reason or "cancelled")
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
            message = entry.work(Reporter(progress, entry.cancel))
        except JobCancelledError as exc:
            log.warning("job %s cancelled: %s", job_id, entry.reason or exc)
            self._end(entry, "cancelled", entry.reason or str(exc) or "cancelled")
            return
        except Exception as exc:
            log.exception("job %s failed", job_id)
            self._end(entry, "failed", f"{type(exc).__name__}: {exc}")
            return
        self._set_status(job_id, status="done", progress=1.0, message=message,
                         finished_at=datetime.now(UTC))
        self._entries.pop(job_id, None)

    def begin_shutdown(self) -> None:
        """Take no more jobs and cancel every one: the queued ones end `cancelled` at
        once, the running ones are told to stop (a cohort's child process is
        terminated) and end `cancelled` in their lane; what each was producing ends
        with the same reason. Does not wait; `shutdown` does."""
        if self._closing:
            return
        self._closing = True
        reason = f"cancelled: the server shut down at {now_text()}"
        dropped = [e for lane in self._lanes.values() for e in lane.close(reason)]
        for entry in dropped:
            try:
                self._end(entry, "cancelled", reason)
            except Exception:  # one job's bookkeeping must not keep the others queued
                log.exception("job %s: not marked cancelled", entry.job_id)

    def shutdown(self, wait_s: float = SHUTDOWN_WAIT_S) -> None:
        """`begin_shutdown`, then wait at most `wait_s` for the running jobs to end."""
        self.begin_shutdown()
        deadline = time.monotonic() + wait_s
        for lane in self._lanes.values():
            if not lane.join(max(0.0, deadline - time.monotonic())):
                log.warning("job lane %s still busy after %.0f s; the next start marks "
                            "its job interrupted", lane.name, wait_s)


def recover(sessions: sessionmaker[Session]) -> list[str]:
    """At start-up, before any job runs: jobs left `queued` or `running` by a previous
    process (killed, or a shutdown that could not wait) end `failed`, and so do the
    model sets still `fitting`, utility sets still `computing` and cohorts still queued
    or running, each with the reason. Returns what was closed, for the log."""
    reason = f"interrupted by a server restart at {now_text()}"
    closed: list[str] = []
    when = datetime.now(UTC)
    with sessions() as db:
        for job in db.scalars(select(Job).where(Job.status.in_(UNFINISHED))):
            closed.append(f"job {job.id} ({job.kind}, {job.status})")
            job.status, job.message, job.finished_at = "failed", reason, when
        for ms in db.scalars(select(ModelSetRecord).where(ModelSetRecord.status == "fitting")):
            closed.append(f"model set {ms.id}")
            ms.status, ms.error = "failed", reason
        for us in db.scalars(select(UtilitySetRecord)
                             .where(UtilitySetRecord.status == "computing")):
            closed.append(f"utility set {us.id}")
            us.status, us.error = "failed", reason
        for c in db.scalars(select(CohortRecord)
                            .where(CohortRecord.status.in_(UNFINISHED))):
            closed.append(f"cohort {c.id}")
            c.status, c.error, c.finished_at = "failed", reason, when
        db.commit()
    return closed
