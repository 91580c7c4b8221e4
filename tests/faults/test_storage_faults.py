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

from backend.core.config import Settings
from backend.main import create_app
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
