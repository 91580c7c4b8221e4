"""Quotas and throttles hold under concurrency, on SQLite and on PostgreSQL: requests
sent all at once (threads released together against the app) are accepted exactly up to
the limit. Wrong passwords: 10 per account; virtual cohorts: `cohort_jobs_per_account`
per experimenter; replication reports: `replication_jobs_per_account` per account, a
viewer's included, each in its own folder even when started in the same second."""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient
from sqlalchemy import select

from backend.analysis.jobs import JobRunner, QuotaFullError
from backend.core.config import Settings
from backend.db import migrate
from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import Job
from backend.main import create_app
from backend.study import accounts
from tests.login import bearer, create_experimenter, log_in

PASSWORD = "a long enough passphrase"
#: A cohort that still runs when the test ends (the shutdown cancels it).
LONG = {"participants": 1000, "seed": 1, "controllers": ["umc", "eumc", "pec"]}


def all_at_once(n: int, send: Callable[[], Any]) -> list[Any]:
    """`send()` from `n` threads released together; their answers."""
    gate = threading.Barrier(n)

    def one(_: int) -> Any:
        gate.wait()
        return send()

    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(one, range(n)))


@contextmanager
def app_client(settings: Settings, **changes: Any) -> Iterator[TestClient]:
    with TestClient(create_app(settings.model_copy(update={
            "device_spawn_simulator": False, **changes}))) as client:
        yield client


def test_concurrent_wrong_passwords_meet_exactly_the_account_limit(
        settings: Settings, experimenter: dict[str, str]) -> None:
    wrong = {"username": experimenter["username"], "password": "not the password"}
    with app_client(settings) as client:
        codes = all_at_once(25, lambda: client.post("/api/auth/token", json=wrong).status_code)
        assert Counter(codes) == {401: accounts.MAX_FAILURES_PER_ACCOUNT,
                                  429: 25 - accounts.MAX_FAILURES_PER_ACCOUNT}
        # The right password waits too, and says for how long.
        r = client.post("/api/auth/token", json=experimenter)
        assert r.status_code == 429 and 0 < int(r.headers["retry-after"]) <= 15 * 60 + 1


def test_right_passwords_give_their_attempt_back(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    limit = accounts.MAX_FAILURES_PER_ACCOUNT
    try:
        with make_session_factory(engine)() as db:
            for _ in range(2 * limit):  # logins that succeed: each attempt given back
                assert accounts.take_attempt(db, "ada", "10.0.0.1") is None
                accounts.give_back_attempt(db, "ada", "10.0.0.1")
                db.commit()
            for _ in range(limit):  # failures: kept
                assert accounts.take_attempt(db, "ada", "10.0.0.1") is None
                db.commit()
            wait = accounts.take_attempt(db, "ada", "10.0.0.1")
            assert wait is not None and 0 < wait <= 15 * 60 + 1
            # Another account from the same address still may, up to the address's limit.
            assert accounts.take_attempt(db, "bob", "10.0.0.1") is None
    finally:
        engine.dispose()


def test_concurrent_cohorts_of_one_experimenter_meet_exactly_the_quota(
        settings: Settings, experimenter: dict[str, str], db_url: str) -> None:
    with app_client(settings, cohort_jobs_per_account=3) as client:
        log_in(client, experimenter)
        answers = all_at_once(10, lambda: client.post("/api/cohorts", json=LONG))
        codes = Counter(r.status_code for r in answers)
        assert codes == {202: 3, 409: 7}, [r.text[:200] for r in answers]
        refused = next(r for r in answers if r.status_code == 409)
        assert "at most 3 may be queued or running" in refused.json()["detail"]
        # Exactly three cohorts were recorded: a refused request left nothing behind.
        assert len(client.get("/api/cohorts").json()) == 3
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        jobs = list(db.scalars(select(Job).where(Job.kind == "cohort")))
    engine.dispose()
    # The shutdown cancelled them and freed their slots.
    assert sorted(j.status for j in jobs) == ["cancelled"] * 3
    assert [j.quota_slot for j in jobs] == [None] * 3


def test_replication_reports_are_limited_per_account_a_viewers_included(
        settings: Settings, experimenter: dict[str, str], db_url: str,
        tmp_path: Path) -> None:
    create_experimenter(db_url, "vera", PASSWORD)
    with app_client(settings, run_dir=tmp_path, replication_jobs_per_account=2) as client:
        log_in(client, experimenter)
        study = client.post("/api/studies", json={"name": "shared"}).json()["id"]
        assert client.put(f"/api/studies/{study}/members",
                          json={"username": "vera", "role": "viewer"}).status_code == 200
        viewer = bearer(client, {"username": "vera", "password": PASSWORD})
        body = {"seeds": 2, "participants": 2}
        answers = all_at_once(6, lambda: client.post("/api/replication", json=body,
                                                     headers=viewer))
        assert Counter(r.status_code for r in answers) == {202: 2, 409: 4}, \
            [r.text[:200] for r in answers]
        assert "replication_jobs_per_account" in next(
            r for r in answers if r.status_code == 409).json()["detail"]


def test_reports_started_in_the_same_second_get_their_own_folders(
        settings: Settings, experimenter: dict[str, str], tmp_path: Path) -> None:
    with app_client(settings, run_dir=tmp_path, replication_jobs_per_account=6) as client:
        log_in(client, experimenter)
        answers = all_at_once(6, lambda: client.post("/api/replication",
                                                     json={"seeds": 2, "participants": 2}))
        assert [r.status_code for r in answers] == [202] * 6
        folders = [r.json()["folder"] for r in answers]
        assert len(set(folders)) == 6, folders
        made = {p.name for p in (tmp_path / "replication").iterdir()}
        assert made == set(folders)
        assert all(f"-job{r.json()['job_id']}-" in r.json()["folder"] for r in answers)


def test_the_job_runner_hands_out_exactly_the_quotas_slots(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    sessions = make_session_factory(engine)
    create_experimenter(db_url, "owner", PASSWORD)
    runner = JobRunner(sessions)
    try:
        def reserve() -> int | str:
            try:
                return runner.reserve("cohort", lane="cohort", owner_id=1, quota=3)
            except QuotaFullError as exc:
                return f"full: {exc.unfinished}"

        got = all_at_once(12, reserve)
        ids = sorted(g for g in got if isinstance(g, int))
        assert len(ids) == 3 and got.count(f"full: {ids}") == 9
        with sessions() as db:
            slots = sorted(s for s in db.scalars(select(Job.quota_slot)) if s is not None)
        assert slots == [0, 1, 2]
        # A job that ends frees its slot for the next one; other accounts have their own.
        runner.abandon(ids[1], "cancelled by the test")
        again = runner.reserve("cohort", lane="cohort", owner_id=1, quota=3)
        assert runner.reserve("cohort", lane="cohort", owner_id=None, quota=3) > again
        with sessions() as db:
            assert db.get(Job, again).quota_slot == 1  # type: ignore[union-attr]
    finally:
        runner.shutdown(1.0)
        engine.dispose()
