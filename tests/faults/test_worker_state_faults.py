"""One state machine for the worker and the study: stale state may never lock.

Each test does what a user could do with the API on a real worker process (simulated
wearer in the worker) and checks the outcome in the database: no controller survives
its trial, one trial at a time, no silent controller change, trials closed with their
real tick counts.

The simulated wearer runs sped up (`SIM_SPEED`) where a test waits on the wearer's
movement: what these tests assert is which controller runs and what is stored, never
when a sample arrives, and a sped-up simulation skips no tick (a late reader gets the
samples due meanwhile, in order; it waits for the database, `Runtime.
_wait_for_recorder`), so the same squats are seen in an eighth of the wall time.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.evidence_tables import Recording, Trial
from backend.db.models import Run
from backend.main import create_app
from tests.databases import AccountTemplates, fresh_database, postgres_server
from tests.faults.busy import Spinners
from tests.faults.served import make_trials, stored_ticks
from tests.live_server import running_server
from tests.login import PASSWORD, USERNAME, bearer, create_experimenter
from tests.polling import wait_for

pytestmark = pytest.mark.slow

#: The simulated wearer this many times faster than real time.
SIM_SPEED = 8.0


def _trial(db_url: str, trial_id: int) -> Trial:
    engine = make_engine(db_url)
    with Session(engine) as db:
        trial = db.get(Trial, trial_id)
        assert trial is not None
        db.expunge(trial)
    engine.dispose()
    return trial


def _run(db_url: str, run_id: int) -> Run:
    engine = make_engine(db_url)
    with Session(engine) as db:
        run = db.get(Run, run_id)
        assert run is not None
        db.expunge(run)
    engine.dispose()
    return run


def test_parallel_trial_starts_one_wins(settings: Settings, experimenter: dict[str, str],
                                        db_url: str, spinners: Spinners) -> None:
    """Four starts at once on a loaded machine: every core is busy from just before the
    starts (the race) to the end; the server and its worker start before the load."""
    settings = settings.model_copy(update={"start_worker": True,
                                           "device_script": "walking"})
    ids = make_trials(db_url, USERNAME, ("pec", "pec", "pec", "pec"))
    with running_server(settings) as base, httpx.Client(base_url=base, timeout=60) as c:
        token = c.post("/api/auth/token", json=experimenter).json()["access_token"]
        c.headers["Authorization"] = f"Bearer {token}"
        wait_for(lambda: c.get("/api/health").json()["worker"]["ticks"] > 20, 90, "ticks")
        spinners.start()
        codes: dict[int, int] = {}
        barrier = threading.Barrier(len(ids))

        def start(tid: int) -> None:
            with httpx.Client(base_url=base, timeout=60, headers=c.headers) as own:
                barrier.wait()
                codes[tid] = own.post(f"/api/trials/{tid}/start", json={}).status_code

        threads = [threading.Thread(target=start, args=(tid,)) for tid in ids]
        for t in threads:
            t.start()
        for t in threads:
            t.join(120)
        assert sorted(codes.values()) == [200, 409, 409, 409], codes
        winner = next(tid for tid, code in codes.items() if code == 200)
        statuses = {tid: _trial(db_url, tid).status for tid in ids}
        assert statuses == {tid: "running" if tid == winner else "planned" for tid in ids}
        # A recording cannot start beside it either.
        sess = _session_of(db_url, winner)
        r = c.post(f"/api/sessions/{sess}/recordings", json={"label": "x"})
        assert r.status_code == 409


def _session_of(db_url: str, trial_id: int) -> int:
    return _trial(db_url, trial_id).session_id


def test_the_database_refuses_a_second_running_trial_or_recording(db_url: str,
                                                                 experimenter: Any) -> None:
    a, b = make_trials(db_url, USERNAME, ("pec", "umc"))
    engine = make_engine(db_url)
    with Session(engine) as db:
        db.execute(update(Trial).where(Trial.id == a).values(status="running"))
        db.commit()
        with pytest.raises(IntegrityError):
            db.execute(update(Trial).where(Trial.id == b).values(status="running"))
            db.commit()
        db.rollback()
        sess = db.scalar(select(Trial.session_id).where(Trial.id == a))
        db.add(Recording(session_id=sess, status="recording"))
        db.commit()
        db.add(Recording(session_id=sess, status="recording"))
        with pytest.raises(IntegrityError):
            db.commit()
        db.rollback()
        # Ended ones are not limited.
        db.add_all([Recording(session_id=sess, status="stopped") for _ in range(2)])
        db.commit()
    engine.dispose()


def test_server_start_closes_what_a_dead_server_left(settings: Settings, db_url: str,
                                                    experimenter: Any, tmp_path: Path) -> None:
    """The state a SIGKILLed server leaves (trial running, run open, ticks stored) is
    closed at the next start; the end-to-end kill is in test_process_faults."""
    from datetime import UTC, datetime

    from backend.db import migrate
    from backend.live.recorder import TickRecorder
    from backend.worker.messages import RunStarted, TickBatch
    from controller.tick_record import TickRecord

    trial_id, = make_trials(db_url, USERNAME, ("pec",))
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    run_id = rec.run_started(RunStarted(1, "pec", {}, "sim", 1), "sim")
    rec.add(TickBatch.from_records(1, (TickRecord(seq=i, t=i * 0.01) for i in range(137))))
    assert rec.flush() == 137
    with Session(engine) as db:
        db.execute(update(Trial).where(Trial.id == trial_id).values(
            status="running", run_id=run_id, started_at=datetime.now(UTC)))
        db.commit()
    engine.dispose()

    with TestClient(create_app(settings)):
        pass
    trial = _trial(db_url, trial_id)
    assert (trial.status, trial.tick_count) == ("interrupted", 137)
    assert "server stopped" in trial.end_reason
    run = _run(db_url, run_id)
    assert run.tick_count == 137 and run.ended_at is not None


# The tests that drive one shared server's worker through the API come last: the
# module's shared server (sped-up squats) stops when the module ends, so it idles
# beside no other test.


@pytest.fixture(scope="module")
def live_server(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path],
                account_templates: AccountTemplates) -> Iterator[tuple[TestClient, str]]:
    """One server with its worker (in-process simulated squats, sped up), logged in by
    token, and its database, for the tests of this module that drive a worker through
    the API: starting a server and its worker costs seconds of CPU, and each test makes
    its own study and trial and starts from the state `live` restores."""
    folder = tmp_path_factory.mktemp("live-server")
    with fresh_database(folder) as db_url:
        server = None if db_url.startswith("sqlite") else postgres_server()
        if not account_templates.fill(db_url, server):
            create_experimenter(db_url)
        models, utilities = default_sets
        settings = Settings(  # type: ignore[call-arg]
            database_url=db_url, start_worker=True, models_path=models,
            utilities_dir=utilities, device_kind="sim", demo=False, _env_file=None,
            device_script="squat-sequence", device_speed=SIM_SPEED)
        with TestClient(create_app(settings)) as client:
            client.headers.update(bearer(client, {"username": USERNAME,
                                                  "password": PASSWORD}))
            yield client, db_url


@pytest.fixture
def live_db(live_server: tuple[TestClient, str]) -> str:
    """The database of the shared server."""
    return live_server[1]


@pytest.fixture
def live(live_server: tuple[TestClient, str]) -> TestClient:
    """The shared server as a new one offers itself, whatever the test before left: no
    trial running, the worker alive and ticking, running `none`."""
    client, db_url = live_server
    engine = make_engine(db_url)
    with Session(engine) as db:
        running = db.scalars(select(Trial.id).where(Trial.status == "running")).all()
    engine.dispose()
    for trial_id in running:
        client.post(f"/api/trials/{trial_id}/stop", json={"outcome": "aborted"})
    if not client.get("/api/health").json()["worker"]["alive"]:
        assert client.post("/api/worker/restart").status_code == 200
    r = client.post("/api/worker/controller", json={"name": "none"})
    assert r.status_code == 200, r.text
    wait_for(lambda: (w := client.get("/api/health").json()["worker"])["ticks"] > 20
             and w["controller"] == "none", 90, "the worker's ticks under `none`")
    return client


def _start_pec_until_it_locks(client: TestClient, db_url: str, trial_id: int) -> int:
    r = client.post(f"/api/trials/{trial_id}/start", json={})
    assert r.status_code == 200, r.text
    run_id = int(r.json()["run_id"])
    # The PEC locks on the first squat (a few seconds into the script).
    wait_for(lambda: any(stored_ticks(db_url, run_id, "lock_left")), 60,
             "a lock command in the trial")
    return run_id


def _locks_in_new_run(client: TestClient, db_url: str, old_run: int, ticks: int) -> int:
    """Lock commands in the run after `old_run`, once it holds at least `ticks` ticks
    and the wearer's first whole squat (down and up again: what the dead trial's PEC
    locked on)."""
    def new_run() -> int | None:
        run_id = client.get("/api/health").json()["database"]["current_run_id"]
        return run_id if run_id not in (None, old_run) else None

    run_id = wait_for(new_run, 60, "the restarted worker's run")
    assert _run(db_url, run_id).controller == "none"

    def squatted() -> bool:
        truth = stored_ticks(db_url, run_id, "truth_activity")
        return len(truth) >= ticks and "squat" in truth \
            and "stand" in truth[truth.index("squat"):]

    wait_for(squatted, 60, f"{ticks} new ticks and a whole squat")
    locks = stored_ticks(db_url, run_id, "lock_left") + stored_ticks(db_url, run_id,
                                                                      "lock_right")
    return sum(bool(x) for x in locks)


@pytest.mark.parametrize("how", ["stop", "sigkill"])
def test_a_restarted_worker_never_resumes_a_dead_trials_controller(
        live: TestClient, live_db: str, how: str) -> None:
    db_url = live_db
    trial_id, = make_trials(db_url, USERNAME, ("pec",))
    run_id = _start_pec_until_it_locks(live, db_url, trial_id)
    if how == "stop":
        assert live.post("/api/worker/stop").status_code == 200
    else:
        os.kill(live.get("/api/health").json()["worker"]["pid"], signal.SIGKILL)

    # Closed as interrupted when noticed, with the real tick count and the reason.
    trial = wait_for(lambda: (t := _trial(db_url, trial_id)).status == "interrupted" and t,
                     10, "the trial to be interrupted")
    stored = len(stored_ticks(db_url, run_id))
    assert trial.tick_count == stored > 0
    expected = "stopped by the experimenter" if how == "stop" else "SIGKILL"
    assert expected in trial.end_reason
    run = _run(db_url, run_id)
    assert run.ended_at is not None and run.tick_count == stored
    # The experimenter's abort comes too late: nothing is running any more.
    r = live.post(f"/api/trials/{trial_id}/stop", json={"outcome": "aborted"})
    assert r.status_code == 409 and "interrupted" in r.text

    assert live.post("/api/worker/restart").status_code == 200
    assert live.get("/api/health").json()["worker"]["controller"] == "none"
    # 3 s and a whole squat with nothing that locks: not one lock command.
    assert _locks_in_new_run(live, db_url, run_id, 300) == 0


def test_no_controller_change_while_a_trial_runs_and_counts_close_it(
        live: TestClient, live_db: str) -> None:
    db_url = live_db
    trial_id, = make_trials(db_url, USERNAME, ("pec",))
    run_id = _start_pec_until_it_locks(live, db_url, trial_id)
    r = live.post("/api/worker/controller", json={"name": "none"})
    assert r.status_code == 409 and f"trial {trial_id}" in r.text
    r = live.post("/api/worker/simulation", json={"seed": 2, "script": "walking"})
    assert r.status_code == 409
    assert live.get("/api/health").json()["database"]["current_run_id"] == run_id

    r = live.post(f"/api/trials/{trial_id}/stop", json={"outcome": "completed"})
    assert r.status_code == 200, r.text
    body = r.json()
    stored = len(stored_ticks(db_url, run_id))
    assert body["status"] == "completed" and body["tick_count"] == stored > 0
    assert body["quality_flags"] == {}  # an unbroken device clock
    run = _run(db_url, run_id)
    assert run.controller == "pec" and run.tick_count == stored
    # Once the trial is over the controller may change again.
    assert live.post("/api/worker/controller", json={"name": "none"}).status_code == 200
