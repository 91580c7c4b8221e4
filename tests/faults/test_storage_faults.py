"""Storage faults: the database refuses writes for a while (another process holds its
write lock: SQLite answers "database is locked", as it answers "disk is full" — the
writer cannot tell the two apart and must handle both the same way).

Memory stays bounded (the backlog limit), the loss is counted exactly, the worker
keeps controlling, and health returns to ok once writes succeed again.
"""

from __future__ import annotations

import sqlite3

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.engine import make_url
from sqlalchemy.exc import OperationalError

from backend.core.config import Settings
from backend.main import create_app
from backend.worker.messages import RunStarted
from tests.faults.served import stored_ticks
from tests.login import bearer
from tests.polling import wait_for

pytestmark = pytest.mark.slow

LIMIT = 150  # ticks: 1.5 s at 100 Hz; the busy timeout alone (5 s) overflows it


def test_write_failures_bound_memory_count_the_loss_and_recover(
        settings: Settings, experimenter: dict[str, str], db_url: str) -> None:
    if not db_url.startswith("sqlite"):
        pytest.skip("injects the fault through SQLite's file lock")
    settings = settings.model_copy(update={"start_worker": True, "db_backlog_limit": LIMIT})
    path = make_url(db_url).database
    assert path
    with TestClient(create_app(settings)) as client:
        client.headers.update(bearer(client, experimenter))
        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        run_id = wait_for(lambda: runtime.recorder.written > 50
                          and runtime.recorder.current_run_id, 90, "ticks written")
        blocker = sqlite3.connect(path, isolation_level=None)
        blocker.execute("BEGIN IMMEDIATE")  # holds the write lock: every insert fails
        try:
            wait_for(lambda: runtime.recorder.failures >= 2, 30, "two failed writes")
            wait_for(lambda: runtime.recorder.dropped > 0, 30, "the backlog to overflow")
            h = runtime.health()
            assert h.status == "degraded" and "locked" in h.database.last_error
            assert h.database.backlog <= LIMIT and h.database.ticks_dropped > 0
            ticks_then = h.worker.ticks
            wait_for(lambda: runtime.health().worker.ticks > ticks_then + 50, 30,
                     "the worker to go on ticking")
            assert runtime.recorder.backlog <= LIMIT
        finally:
            blocker.execute("ROLLBACK")
            blocker.close()
        # Writes succeed again: health is ok again, the loss stays on record.
        wait_for(lambda: client.get("/api/health").json()["status"] == "ok", 30,
                 "health back to ok")
        body = client.get("/api/health").json()["database"]
        assert body["last_error"] == "" and body["write_failures"] >= 2
        assert body["ticks_dropped"] == runtime.recorder.dropped > 0
        outbox_drops = client.get("/api/health").json()["worker"]["dropped_records"]
    # Every tick received is stored, except exactly the ones counted as dropped.
    dropped = runtime.recorder.dropped
    seqs = stored_ticks(db_url, run_id, "seq")
    assert seqs == sorted(seqs) and outbox_drops == 0
    missing = (seqs[-1] - seqs[0] + 1) - len(seqs)
    assert missing == dropped


def test_a_run_the_database_refuses_is_never_answered_with_another(
        settings: Settings, experimenter: dict[str, str]) -> None:
    """The database refuses the row of the run a recording's start makes, after a worker
    restart (whose runs are numbered from 1 again, as the old worker's were): the start
    is refused with the reason and the worker released; it never gets the id of the old
    worker's run with the same number (that run's data would become the recording's),
    and the next start, with the database back, gets a run of its own."""
    settings = settings.model_copy(update={"start_worker": True})
    with TestClient(create_app(settings)) as client:
        client.headers.update(bearer(client, experimenter))
        study = client.post("/api/studies", json={"name": "refused run"}).json()["id"]
        part = client.post(f"/api/studies/{study}/participants", json={"code": "R1"}).json()
        sid = client.post(f"/api/participants/{part['id']}/sessions", json={
            "kind": "data_collection", "precompression_pct": 25}).json()["id"]
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 5, 60,
                 "the worker's ticks")
        first = client.post(f"/api/sessions/{sid}/recordings", json={"label": "a"})
        assert first.status_code == 201, first.text
        assert client.post(f"/api/recordings/{first.json()['id']}/stop").status_code == 200
        assert client.post("/api/worker/restart").status_code == 200
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 5, 60,
                 "the restarted worker's ticks")
        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        real = runtime.recorder.run_started
        refused: list[int] = []

        def locked(msg: RunStarted, kind: str) -> int:
            if not refused:
                refused.append(msg.run_token)
                raise OperationalError("INSERT INTO runs", {}, Exception("database is locked"))
            return real(msg, kind)

        runtime.recorder.run_started = locked
        try:
            second = client.post(f"/api/sessions/{sid}/recordings", json={"label": "b"})
        finally:
            runtime.recorder.run_started = real
        assert second.status_code == 409, second.text
        assert "could not be stored" in second.text and "database is locked" in second.text
        assert refused  # the refused run's number was one the old worker had used too
        rows = client.get(f"/api/sessions/{sid}/recordings").json()
        assert [r["label"] for r in rows] == ["a"]
        wait_for(lambda: client.get("/api/health").json()["worker"]["controller"] == "none",
                 30, "the worker released")
        third = client.post(f"/api/sessions/{sid}/recordings", json={"label": "c"})
        assert third.status_code == 201, third.text
        assert third.json()["run_id"] not in {first.json()["run_id"]}
        assert client.post(f"/api/recordings/{third.json()['id']}/stop").status_code == 200
