"""The background job runner: lanes (a study job never waits behind cohorts), accounts
taking turns, cancellation at shutdown (queued and running jobs end `cancelled` with the
reason, and so does what they were producing), a child-process job terminated on
cancel, and the start-up reconciliation of what a killed server left running."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from sqlalchemy.orm import Session, sessionmaker

from backend.analysis import job_process, jobs
from backend.analysis.jobs import JobCancelledError, JobRunner, Reporter
from backend.core.errors import ConflictError
from backend.db import migrate
from backend.db.cohorts import CohortRecord
from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import Job, ModelSetRecord, UtilitySetRecord
from backend.db.models import Study
from backend.study import accounts
from tests.faults.served import alive
from tests.polling import wait_for


@pytest.fixture
def sessions(db_url: str) -> Iterator[sessionmaker[Session]]:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    yield make_session_factory(engine)
    engine.dispose()


def _job(sessions: sessionmaker[Session], job_id: int) -> Job:
    with sessions() as db:
        job = db.get(Job, job_id)
        assert job is not None
        db.expunge(job)
        return job


def _until_cancelled(progress: Reporter) -> str:
    """A long computation: reports progress until told to stop."""
    while True:
        progress(0.5)
        progress.cancelled.wait(0.05)


def test_shutdown_cancels_running_and_queued_jobs_with_the_reason(
        sessions: sessionmaker[Session]) -> None:
    runner = JobRunner(sessions)
    failures: dict[int, str] = {}
    ids = []
    def told(target: int) -> Callable[[str], None]:
        return lambda message: failures.__setitem__(target, message)

    for target in (1, 2):
        job_id, _ = runner.submit("cohort", target, _until_cancelled, told(target),
                                  lane="cohort", owner_id=None)
        ids.append(job_id)
    wait_for(lambda: _job(sessions, ids[0]).status == "running", 30, "the first job to run")
    assert _job(sessions, ids[1]).status == "queued"
    runner.shutdown(wait_s=30)
    for job_id in ids:
        job = _job(sessions, job_id)
        assert job.status == "cancelled" and "server shut down" in job.message
        assert job.finished_at is not None
    # What each job was producing is told the same reason (running and queued alike).
    assert set(failures) == {1, 2}
    assert all("server shut down" in m for m in failures.values())
    with pytest.raises(ConflictError, match="shutting down"):
        runner.submit("cohort", 3, _until_cancelled, lane="cohort")


def test_a_study_job_does_not_wait_behind_cohorts(sessions: sessionmaker[Session]) -> None:
    runner = JobRunner(sessions)
    try:
        cohorts = [runner.submit("cohort", t, _until_cancelled, lane="cohort")[0]
                   for t in (1, 2)]
        wait_for(lambda: _job(sessions, cohorts[0]).status == "running", 30, "a cohort")
        fit, done = runner.submit("fit_model_set", 1, lambda p: "fitted")
        done.result(timeout=30)
        assert _job(sessions, fit).status == "done"
        assert [_job(sessions, c).status for c in cohorts] == ["running", "queued"]
    finally:
        runner.shutdown(wait_s=30)


def test_accounts_take_turns_within_a_lane(sessions: sessionmaker[Session]) -> None:
    with sessions() as db:
        a, b = (accounts.create_user(db, name, "a long enough passphrase")
                for name in ("anna", "bert"))
        db.commit()
        owners = (a.id, b.id)
    runner = JobRunner(sessions)
    gate = threading.Event()
    order: list[str] = []

    def blocked(progress: Reporter) -> str:
        gate.wait(30)
        return "gate"

    def record(name: str) -> jobs.Work:
        def work(progress: Reporter) -> str:
            order.append(name)
            return name
        return work

    try:
        gate_job, _ = runner.submit("cohort", 0, blocked, lane="cohort", owner_id=owners[0])
        wait_for(lambda: _job(sessions, gate_job).status == "running", 30, "the gate job")
        futures = [runner.submit("cohort", n, record(f"a{n}"), lane="cohort",
                                 owner_id=owners[0])[1] for n in (1, 2, 3)]
        futures.append(runner.submit("cohort", 9, record("b1"), lane="cohort",
                                     owner_id=owners[1])[1])
        gate.set()
        for f in futures:
            f.result(timeout=30)
        # Bert's one job comes before Anna's second, not after her third.
        assert order == ["a1", "b1", "a2", "a3"]
    finally:
        runner.shutdown(wait_s=30)


def test_a_failing_job_is_failed_with_its_reason(sessions: sessionmaker[Session]) -> None:
    runner = JobRunner(sessions)
    told: list[str] = []

    def broken(progress: Reporter) -> str:
        raise ValueError("segment 7 contains bad samples")

    try:
        job_id, done = runner.submit("fit_model_set", 1, broken, told.append)
        done.result(timeout=30)
        job = _job(sessions, job_id)
        assert job.status == "failed" and job.message == told[0]
        assert "segment 7 contains bad samples" in job.message
    finally:
        runner.shutdown(wait_s=30)


def report_pid_forever(pid_file: str, progress: jobs.Progress) -> None:
    """A child job that never ends on its own (module level: the child is spawned)."""
    Path(pid_file).write_text(str(os.getpid()))
    while True:
        progress(0.1)
        threading.Event().wait(0.05)


def fail_in_child(progress: jobs.Progress) -> None:
    raise ValueError("no default model set at /nowhere")


def test_a_child_job_is_terminated_when_cancelled(tmp_path: Path) -> None:
    cancelled = threading.Event()
    pid_file = tmp_path / "child.pid"
    seen: list[float] = []
    result: list[BaseException] = []

    def run() -> None:
        try:
            job_process.run_in_child(report_pid_forever, (str(pid_file),), seen.append,
                                     cancelled)
        except BaseException as exc:  # the test inspects it
            result.append(exc)

    thread = threading.Thread(target=run)
    thread.start()
    wait_for(lambda: seen and pid_file.is_file() and pid_file.read_text(), 60,
             "the child to report progress")
    pid = int(pid_file.read_text())
    cancelled.set()
    thread.join(30)
    assert not thread.is_alive()
    assert isinstance(result[0], JobCancelledError)
    wait_for(lambda: not alive(pid), 10, "the cancelled child to exit")


def test_a_child_failure_is_the_jobs_failure() -> None:
    with pytest.raises(job_process.JobProcessError, match="no default model set"):
        job_process.run_in_child(fail_in_child, (), lambda f: None, threading.Event())


def test_start_up_reconciles_what_a_killed_server_left(
        sessions: sessionmaker[Session]) -> None:
    with sessions() as db:
        study = Study(name="s")
        db.add(study)
        db.flush()
        fitting = ModelSetRecord(study_id=study.id, name="m", status="fitting")
        ready = ModelSetRecord(study_id=study.id, name="r", status="ready", document={})
        computing = UtilitySetRecord(study_id=study.id, name="u", precompression_pct=25.0,
                                     human_source="simulated", status="computing")
        running = CohortRecord(config={}, status="running")
        queued = CohortRecord(config={}, status="queued")
        db.add_all([fitting, ready, computing, running, queued])
        db.flush()
        rows = [Job(kind="fit_model_set", target_id=fitting.id, status="running"),
                Job(kind="compute_utilities", target_id=computing.id, status="queued"),
                Job(kind="cohort", target_id=running.id, status="running", lane="cohort"),
                Job(kind="cohort", target_id=queued.id, status="queued", lane="cohort"),
                Job(kind="fit_model_set", target_id=ready.id, status="done",
                    message="fitted 6 demonstrations")]
        db.add_all(rows)
        db.commit()
        ids = [r.id for r in rows]
        set_ids = (fitting.id, ready.id, computing.id, running.id, queued.id)

    closed = jobs.recover(sessions)
    assert len(closed) == 4 + 4

    for job_id in ids[:4]:
        job = _job(sessions, job_id)
        assert job.status == "failed" and job.finished_at is not None
        assert job.message.startswith("interrupted by a server restart at ")
    assert _job(sessions, ids[4]).status == "done"
    with sessions() as db:
        ms, ok = db.get(ModelSetRecord, set_ids[0]), db.get(ModelSetRecord, set_ids[1])
        us = db.get(UtilitySetRecord, set_ids[2])
        c1, c2 = db.get(CohortRecord, set_ids[3]), db.get(CohortRecord, set_ids[4])
        assert ms is not None and ok is not None and us is not None
        assert c1 is not None and c2 is not None
        for row in (ms, us, c1, c2):
            assert row.status == "failed"
            assert row.error.startswith("interrupted by a server restart at ")
        assert ok.status == "ready" and ok.error == ""
    assert jobs.recover(sessions) == []  # nothing left to close
