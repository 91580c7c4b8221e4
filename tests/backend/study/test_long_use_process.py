"""Long use on the running processes: a real worker and the simulated wearer (sped up)
run the UMC in two long-use sessions, one of lifting and one of walking, with an event
marked during the first; every tick is stored with the trial, and the wearer's progress
counts both sessions from the simulation's truth."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from backend import bootstrap
from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.evidence_tables import ModelSetRecord, UtilitySetRecord
from backend.main import create_app
from tests.login import log_in
from tests.polling import wait_for

pytestmark = pytest.mark.slow

DEVICE_SECONDS = 40.0
#: The simulated wearer this many times faster than real time: a timed run ends after
#: its device time, whatever the pace, and the simulation waits for the database
#: (nothing is dropped), so each session takes 2.5 s of wall time, of which the first
#: 0.3 s pass before the event is marked (what the marker needs: a running trial).
SIM_SPEED = 16.0


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def _sets(settings: Settings, study_id: int) -> tuple[int, int]:
    """The server's default model and utility sets as ready sets of the study (what the
    demo study holds; fitting them here would only repeat the fitting tests)."""
    models = json.loads(Path(settings.models_path).read_text())
    utilities = json.loads(bootstrap.utilities_path(settings.utilities_dir, 25.0).read_text())
    with Session(make_engine(settings.database_url)) as db:
        ms = ModelSetRecord(study_id=study_id, name="default", status="ready",
                            document=models)
        us = UtilitySetRecord(study_id=study_id, name="default 25 %", precompression_pct=25.0,
                              human_source="simulated", status="ready", document=utilities)
        db.add_all([ms, us])
        db.commit()
        return ms.id, us.id


def _stored(client: TestClient) -> int:
    return int(client.get("/api/health").json()["database"]["ticks_written"])


def _use(client: TestClient, session_id: int, sets: tuple[int, int], script: str,
         mark: str | None = None) -> dict[str, Any]:
    """One session of use: the wearer follows `script`, the UMC runs for DEVICE_SECONDS
    of device time (a timed run: the worker ends it), optionally an event is marked
    while it runs; then the experimenter stops it."""
    _ok(client.post("/api/worker/simulation", json={"seed": 3, "script": script}))
    wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] >= 20, 60,
             "the worker to tick", poll=0.2)
    before = _stored(client)
    trial = _ok(client.post(f"/api/sessions/{session_id}/long-use", json={
        "controller": "umc", "model_set_id": sets[0], "utility_set_id": sets[1],
        "duration_s": DEVICE_SECONDS}), 201)
    assert trial["status"] == "running" and trial["task"] == "long_use"
    assert trial["config_snapshot"]["model_set"]["id"] == sets[0]
    if mark is not None:
        wait_for(lambda: _stored(client) >= before + 500, 120, "5 s of the trial stored",
                 poll=0.1)
        _ok(client.post(f"/api/sessions/{session_id}/markers", json={"label": mark}), 201)
    wait_for(lambda: client.get("/api/health").json()["worker"]["controller"] == "none"
             and _stored(client) >= before + round(DEVICE_SECONDS * 100), 180,
             "the timed long-use run to end and be stored", poll=0.2)
    done = _ok(client.post(f"/api/trials/{trial['id']}/stop", json={"outcome": "completed"}))
    assert done["status"] == "completed"
    return dict(done)


def test_two_long_use_sessions_on_the_running_processes(settings: Settings,
                                                        experimenter: dict[str, str]) -> None:
    fast = settings.model_copy(update={"start_worker": True, "device_speed": SIM_SPEED,
                                       "device_script": "squat-sequence"})
    with TestClient(create_app(fast)) as client:
        log_in(client, experimenter)
        study = _ok(client.post("/api/studies", json={"name": "Long use"}), 201)["id"]
        pid = _ok(client.post(f"/api/studies/{study}/participants", json={"code": "W01"}),
                  201)["id"]
        sets = _sets(fast, study)
        days = [_ok(client.post(f"/api/participants/{pid}/sessions", json={
            "kind": "long_use", "precompression_pct": 25,
            "started_at": f"2026-12-0{d}T08:00:00Z"}), 201)["id"] for d in (1, 2)]
        lifting = _use(client, days[0], sets, "squat-sequence", mark="box dropped")
        walking = _use(client, days[1], sets, "walking")
        # Exactly the timed device time, every tick stored with its trial.
        assert lifting["tick_count"] == walking["tick_count"] == DEVICE_SECONDS * 100
        ticks = _ok(client.get(f"/api/trials/{lifting['id']}/ticks.json"))["columns"]
        assert len(ticks["t"]) == DEVICE_SECONDS * 100
        assert any(ticks["controller_ran"]) and any(a >= 2 for a in ticks["action"])
        marks = _ok(client.get(f"/api/trials/{lifting['id']}/markers"))
        console = [m for m in marks if m["source"] == "console"]
        assert [m["label"] for m in console] == ["box dropped"]
        assert 0 < console[0]["t"] <= max(ticks["t"])
        # A long-use session has no plan, and its trials are not the study's results.
        assert _ok(client.get(f"/api/studies/{study}/results"))["trials"] == []

        doc = _ok(client.get(f"/api/participants/{pid}/progress"))
        first, second = doc["sessions"]
        assert [first["session_id"], second["session_id"]] == days
        assert first["truth"] == second["truth"] == ["simulation"]
        assert first["hours"] == second["hours"] == pytest.approx(DEVICE_SECONDS / 3600)
        # Squats every ~10 s: lifts, each confirmed by the simulation, recognised by the
        # UMC; no walking bout. The walking day: no lift, a walking bout.
        assert first["lifts"] >= 2 and first["confirmed_lifts"] >= 1
        assert first["unconfirmed_lifts"] == 0 and first["walking_hours"] == 0
        assert first["recognised"] is not None
        assert second["lifts"] == 0 and second["walking_hours"] > 0
        curves = {c["metric"]: c for c in doc["curves"]}
        lph = curves["lifts_per_hour"]["points"]
        assert lph[0]["value"] == pytest.approx(first["lifts"] / first["hours"])
        assert lph[1]["value"] == 0.0
        walk = curves["fp_per_hour_walking"]["points"]
        assert walk[0]["value"] is None
        assert walk[1]["value"] == pytest.approx(second["walking_fp"] / second["walking_hours"])
        rate = curves["lock_rate"]["points"][0]
        assert rate["value"] == pytest.approx(first["correct_locks"] / first["confirmed_lifts"])
        assert curves["lock_rate"]["trend"]["n"] == 1
