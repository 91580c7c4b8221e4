"""The experimenter's lift segments of a trial recorded without simulation labels (as on
hardware): proposed automatically, replaced after checking, refused when they overlap or
leave the trial, and then the ground truth of the results tables.

The ticks are those of `test_results` (a squat at 200-399 recognised and decided
correctly, a stoop left at 500-699 decided wrongly) with the truth columns blanked.
"""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import Trial
from backend.live.recorder import TickRecorder
from backend.worker.messages import RunStarted, TickBatch
from tests.backend.analysis.test_results import N, _ok, _ticks


def _hardware_trial(client: TestClient, settings: Settings) -> tuple[int, int]:
    study = _ok(client.post("/api/studies", json={"name": "Hardware"}), 201)
    part = _ok(client.post(f"/api/studies/{study['id']}/participants",
                           json={"code": "H01"}), 201)
    sess = _ok(client.post(f"/api/participants/{part['id']}/sessions",
                           json={"kind": "evaluation", "precompression_pct": 25}), 201)
    engine = make_engine(settings.database_url)
    rec = TickRecorder(engine)
    run = rec.run_started(RunStarted(1, "umc", {}, "udp", 1), "udp")
    blank = tuple(r.with_(truth_activity="", truth_lift=-1) for r in _ticks())
    rec.add(TickBatch.from_records(1, blank))
    assert rec.flush() == N
    with make_session_factory(engine)() as db:
        trial = Trial(session_id=sess["id"], controller="umc", task="squat-sequence",
                      planned_order=0, status="completed", run_id=run,
                      config_snapshot={"controller": "umc", "settings": {}})
        db.add(trial)
        db.commit()
        tid = trial.id
    engine.dispose()
    return study["id"], tid


def _row(doc: dict[str, Any], metric: str, motion: str) -> str:
    rows = {(r[0], r[1]): r[2] for r in doc["tables"]["performance"]["rows"]}
    return str(rows[(metric, motion)])


def test_segments_make_a_hardware_trial_count(client: TestClient, settings: Settings) -> None:
    study, tid = _hardware_trial(client, settings)
    doc = _ok(client.get(f"/api/studies/{study}/results"))
    assert doc["trials"][0]["truth"] == "none"
    assert "no experimenter segments" in doc["trials"][0]["truth_note"]

    # Proposed automatically: two lifts where the hip flexes, unlabelled (no truth).
    auto = _ok(client.post(f"/api/trials/{tid}/segment"))
    assert [s["label"] for s in auto] == ["unlabelled", "unlabelled"]
    assert 180 <= auto[0]["start"] <= 230 and 370 <= auto[0]["end"] <= 420
    assert 480 <= auto[1]["start"] <= 530 and 670 <= auto[1]["end"] <= 720
    doc = _ok(client.get(f"/api/studies/{study}/results"))
    assert doc["trials"][0]["truth"] == "none"
    assert "unlabelled" in doc["trials"][0]["truth_note"]

    # The experimenter's checked lifts: the same answers as the simulation's truth gave.
    body = [{"start": 200, "peak": 300, "end": 399, "label": "squat"},
            {"start": 500, "peak": 600, "end": 699, "label": "stoop_left"}]
    saved = _ok(client.put(f"/api/trials/{tid}/segments", json=body))
    assert [(s["start"], s["label"], s["source"]) for s in saved] == [
        (200, "squat", "edited"), (500, "stoop_left", "edited")]
    doc = _ok(client.get(f"/api/studies/{study}/results"))
    assert doc["trials"][0]["truth"] == "segments" and doc["trials"][0]["lifts"] == 2
    assert _row(doc, "Intent estimation", "SQ") == "1"
    assert _row(doc, "Intent estimation", "AS") == "0"
    assert _row(doc, "Decision correct", "SQ") == "1"
    assert _row(doc, "Decision wrong", "AS") == "1"

    # Edited segments are not overwritten by a new proposal unless asked.
    r = client.post(f"/api/trials/{tid}/segment")
    assert r.status_code == 409 and "replace=true" in r.text
    assert len(_ok(client.get(f"/api/trials/{tid}/segments"))) == 2


def test_bad_segments_are_refused_and_nothing_changes(client: TestClient,
                                                      settings: Settings) -> None:
    _, tid = _hardware_trial(client, settings)
    good = [{"start": 200, "peak": 300, "end": 399, "label": "squat"}]
    _ok(client.put(f"/api/trials/{tid}/segments", json=good))
    overlap = [{"start": 200, "peak": 300, "end": 399, "label": "squat"},
               {"start": 350, "peak": 450, "end": 520, "label": "stoop_left"}]
    r = client.put(f"/api/trials/{tid}/segments", json=overlap)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", 1, "start"]
    assert "overlaps segment 0 (200..399)" in r.json()["detail"][0]["msg"]
    beyond = [{"start": 1300, "peak": 1350, "end": N + 5, "label": "squat"}]
    r = client.put(f"/api/trials/{tid}/segments", json=beyond)
    assert r.status_code == 422 and f"beyond the trial's {N} ticks" in r.text
    disordered = [{"start": 300, "peak": 200, "end": 399, "label": "squat"}]
    assert client.put(f"/api/trials/{tid}/segments", json=disordered).status_code == 422
    assert [s["start"] for s in _ok(client.get(f"/api/trials/{tid}/segments"))] == [200]
    assert client.get("/api/trials/999999/segments").status_code == 404
