"""Console markers and the running trial: a marker whose newest tick is not the running
trial's (a timed trial past its duration, still running until stopped) is refused with
a 409 naming the trial, not stored on another run without a trial."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.lab.lsl_outlets import TickTime
from backend.live.recorder import TickRecorder
from backend.worker.messages import RunStarted


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def test_a_marker_after_a_timed_trials_ticks_end_is_refused(
        client: TestClient, db_url: str, monkeypatch: pytest.MonkeyPatch) -> None:
    study = _ok(client.post("/api/studies", json={"name": "Markers"}), 201)["id"]
    pid = _ok(client.post(f"/api/studies/{study}/participants", json={"code": "M01"}),
              201)["id"]
    sid = _ok(client.post(f"/api/participants/{pid}/sessions",
                          json={"kind": "long_use", "precompression_pct": 25}), 201)["id"]
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    trial_run = rec.run_started(RunStarted(1, "pec", {}, "sim", 1), "sim")
    idle_run = rec.run_started(RunStarted(2, "none", {}, "sim", 1), "sim")
    with make_session_factory(engine)() as db:
        trial = Trial(session_id=sid, controller="pec", task="long_use", planned_order=0,
                      status="running", run_id=trial_run)
        db.add(trial)
        db.commit()
        tid = trial.id
    app: Any = client.app
    outlets = app.state.lab.outlets
    # The timed run ended at its duration; the worker's next run ticks on.
    monkeypatch.setattr(outlets, "latest", lambda: TickTime(idle_run, 12.0, 100.0))
    r = client.post(f"/api/sessions/{sid}/markers", json={"label": "walking"})
    assert r.status_code == 409, r.text
    assert f"trial {tid}" in r.text and f"/api/trials/{tid}/stop" in r.text
    with make_session_factory(engine)() as db:
        assert db.scalar(select(func.count()).select_from(Marker)) == 0
    # While the trial's own ticks arrive, the marker is the trial's.
    monkeypatch.setattr(outlets, "latest", lambda: TickTime(trial_run, 3.0, 90.0))
    got = _ok(client.post(f"/api/sessions/{sid}/markers", json={"label": "walking"}), 201)
    assert (got["trial_id"], got["run_id"], got["t"]) == (tid, trial_run, 3.0)
    engine.dispose()
