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
from sqlalchemy.exc import IntegrityError, OperationalError
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
FINAL = ("done", "failed", "cancelled")
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


class QuotaFullError(ConflictError):
    """Every slot of the account's quota for this kind of job is held by an unfinished
    job (a 409); `unfinished` are their ids."""

    def __init__(self, kind: str, limit: int, unfinished: list[int]) -> None:
        super().__init__(kind, f"at most {limit} {kind} job(s) may be queued or running "
                         f"per account; unfinished: {unfinished}")
        self.limit, self.unfinished = limit, unfinished


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
        #: Reserved jobs not yet enqueued: their lane and owner.
        self._reserved: dict[int, tuple[str, int | None]] = {}
        self._closing = False
        self._lanes = {name: _Lane(name, self._run) for name in LANES}

    def submit(self, kind: str, target_id: int, work: Work,
               on_failure: Callable[[str], None] | None = None, *, lane: str = "study",
               owner_id: int | None = None, quota: int | None = None
               ) -> tuple[int, Future[None]]:
        """Queue `work(progress) -> message` in `lane`; returns the job id and a future
        that completes when the job has ended, however it ended. `on_failure(reason)`
        is called when the job fails or is cancelled, to leave its product final.
        `quota`: see `reserve`. Refused (`ConflictError`, a 409) once the server is
        shutting down, or when the owner's quota is full (`QuotaFullError`)."""
        job_id = self.reserve(kind, target_id, lane=lane, owner_id=owner_id, quota=quota)
        return job_id, self.enqueue(job_id, work, on_failure)

    def reserve(self, kind: str, target_id: int = 0, *, lane: str = "study",
                owner_id: int | None = None, quota: int | None = None) -> int:
        """Record a queued job that nothing runs yet (`enqueue` runs it, `abandon`
        drops it); returns its id. With `quota` and an owner, the job takes one of the
        owner's `quota` slots for this kind: the unique index on (created_by, kind,
        quota_slot) lets the database refuse a second job in a slot, so requests that
        arrive together cannot exceed the quota (a count read before the insert
        could); `QuotaFullError` when every slot is held by an unfinished job."""
        if lane not in self._lanes:
            raise ValueError(f"unknown job lane {lane!r}; choose from {', '.join(LANES)}")
        slots: list[int | None] = [None]
        if quota is not None and owner_id is not None:
            with self.sessions() as db:
                held = set(db.scalars(select(Job.quota_slot).where(
                    Job.created_by == owner_id, Job.kind == kind,
                    Job.quota_slot.is_not(None))))
            # The free slots first; a held one may be freed meanwhile, and a free one
            # taken: the index decides.
            slots = sorted(range(quota), key=lambda i: (i in held, i))
        for slot in slots:
            with self.sessions() as db:
                job = Job(kind=kind, target_id=target_id, status="queued", progress=0.0,
                          lane=lane, created_by=owner_id, quota_slot=slot)
                db.add(job)
                try:
                    db.commit()
                except IntegrityError:
                    db.rollback()
                    continue
                self._reserved[job.id] = (lane, owner_id)
                return job.id
        assert quota is not None
        with self.sessions() as db:
            unfinished = list(db.scalars(select(Job.id).where(
                Job.created_by == owner_id, Job.kind == kind, Job.status.in_(UNFINISHED))
                .order_by(Job.id)))
        raise QuotaFullError(kind, quota, unfinished)

    def enqueue(self, job_id: int, work: Work, on_failure: Callable[[str], None] | None = None,
                *, target_id: int | None = None) -> Future[None]:
        """Run a reserved job (`target_id`: what it produces, if known only now)."""
        lane, owner_id = self._reserved.pop(job_id)
        if target_id is not None:
            self._set_status(job_id, target_id=target_id)
        entry = _Entry(job_id, work, on_failure, owner_id)
        self._entries[job_id] = entry
        try:
            self._lanes[lane].put(entry)
        except ConflictError:
            self._end(entry, "cancelled", "the server is shutting down: not started")
            raise
        return entry.future

    def abandon(self, job_id: int, reason: str) -> None:
        """A reserved job that will not run ends `cancelled` and frees its slot."""
        self._reserved.pop(job_id, None)
        self._set_status(job_id, status="cancelled", message=reason[:2000],
                         finished_at=datetime.now(UTC))

    def _set(self, job_id: int, **values: object) -> None:
        with self.sessions() as db:
            db.execute(update(Job).where(Job.id == job_id).values(**values))
            db.commit()

    def _set_status(self, job_id: int, **values: object) -> None:
        """A status change must be stored, or a poller waits for ever: retried while
        the database is busy beyond its timeout (a few times, then it raises). A final
        status frees the job's quota slot in the same statement."""
        if values.get("status") in FINAL:
            values["quota_slot"] = None
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
            job.quota_slot = None
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
