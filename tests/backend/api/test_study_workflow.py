"""A study through the API alone, on a real worker and the simulated wearer (sped up):
record demonstrations, segment them, fit models, compute utilities, plan the
counterbalanced evaluation, run trials and export their ticks; then evaluate the motion
models leaving one participant out."""

from __future__ import annotations

import csv
import io
import json
import zipfile
from typing import Any

import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.main import create_app
from tests.login import log_in
from tests.polling import wait_for
from tests.simulation_speed import past_run, ticks_per_second

pytestmark = pytest.mark.slow


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def _job(client: TestClient, job_id: int, timeout: float = 60.0) -> dict[str, Any]:
    job: dict[str, Any] = wait_for(
        lambda: (j := _ok(client.get(f"/api/jobs/{job_id}")))["status"] in ("done", "failed")
        and j, timeout, f"job {job_id} to finish", poll=0.2)
    return job


def _wait_ticks(client: TestClient) -> None:
    wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] >= 20, 60,
             "the worker to tick", poll=0.2)


def _stored(client: TestClient) -> int:
    return int(client.get("/api/health").json()["database"]["ticks_written"])


def _let_run(client: TestClient, device_seconds: float) -> None:
    """Wait until `device_seconds` more of the device's 100 Hz ticks are stored (the
    amount of data, whatever the machine's speed)."""
    target = _stored(client) + round(device_seconds * 100)
    wait_for(lambda: _stored(client) >= target, 120, f"{device_seconds} s more ticks", poll=0.2)


def _record(client: TestClient, session_id: int, script: str, device_seconds: float) -> int:
    _ok(client.post("/api/worker/simulation", json={"seed": 21, "script": script}))
    _wait_ticks(client)
    rec = _ok(client.post(f"/api/sessions/{session_id}/recordings",
                          json={"label": script}), 201)
    _let_run(client, device_seconds)
    rec = _ok(client.post(f"/api/recordings/{rec['id']}/stop"))
    assert rec["status"] == "stopped" and rec["last_tick_id"] > rec["first_tick_id"]
    return int(rec["id"])


def test_a_study_from_participant_to_exported_ticks(
    settings: Settings, experimenter: dict[str, str]
) -> None:
    settings = settings.model_copy(update={"start_worker": True, "device_speed": 5.0,
                                           "device_script": "squat-sequence"})
    with TestClient(create_app(settings)) as client:
        log_in(client, experimenter)
        study = _ok(client.post("/api/studies", json={"name": "Lifting study"}), 201)
        p1 = _ok(client.post(f"/api/studies/{study['id']}/participants",
                             json={"code": "P01", "age": 30, "sex": "female", "height_m": 1.7,
                                   "mass_kg": 65, "consent_date": "2026-11-20"}), 201)
        p2 = _ok(client.post(f"/api/studies/{study['id']}/participants",
                             json={"code": "P02", "age": 41, "sex": "male", "height_m": 1.82,
                                   "mass_kg": 80, "consent_date": "2026-11-21"}), 201)
        dc = _ok(client.post(f"/api/participants/{p1['id']}/sessions",
                             json={"kind": "data_collection", "precompression_pct": 25}), 201)

        # 1. Data collection: squats, then stoops, each recorded and segmented.
        segments: list[dict[str, Any]] = []
        # Device time (the device runs at 5x): what 7 s and 12 s of wall time gave.
        for script, seconds in (("squat-sequence", 35.0), ("stoop-sequence", 60.0)):
            rid = _record(client, dc["id"], script, seconds)
            angles = _ok(client.get(f"/api/recordings/{rid}/angles"))
            assert len(angles["t"]) > 500
            found = _ok(client.post(f"/api/recordings/{rid}/segment"))
            assert found, f"no lifts found in {script}"
            segments += found
        labels = [s["label"] for s in segments]
        assert {"squat", "stoop_left", "stoop_right"} <= set(labels)
        # The experimenter moves an edge: the segment is marked as edited.
        edited = _ok(client.patch(f"/api/segments/{segments[0]['id']}",
                                  json={"start": segments[0]["start"] + 1}))
        assert edited["source"] == "edited"
        bad = client.patch(f"/api/segments/{segments[0]['id']}", json={"end": 10**7})
        assert bad.status_code == 422 and "end" in bad.text

        # 2. Models and utilities as background jobs.
        ms = _ok(client.post(f"/api/studies/{study['id']}/model-sets",
                             json={"name": "P01 demos", "segment_ids": [s["id"] for s in
                                                                        segments]}), 202)
        assert _job(client, ms["job_id"])["status"] == "done"
        doc = _ok(client.get(f"/api/model-sets/{ms['id']}/document"))
        assert doc["format"] == "exostudy.motion_model_set"
        us = _ok(client.post(f"/api/studies/{study['id']}/utility-sets",
                             json={"name": "sim 25", "precompression_pct": 25}), 202)
        assert _job(client, us["job_id"])["status"] == "done"
        curves = _ok(client.get(f"/api/utility-sets/{us['id']}/curves"))
        assert set(curves["differences"]) == {"squat", "stoop_left", "stoop_right"}

        # 3. Evaluation: counterbalanced across participants.
        plans = []
        for p in (p1, p2):
            ev = _ok(client.post(f"/api/participants/{p['id']}/sessions",
                                 json={"kind": "evaluation", "precompression_pct": 25}), 201)
            plan = _ok(client.post(f"/api/sessions/{ev['id']}/trials/plan",
                                   json={"tasks": ["squat-sequence"], "model_set_id": ms["id"],
                                         "utility_set_id": us["id"]}), 201)
            plans.append(plan)
        assert [t["controller"] for t in plans[0]] == ["umc", "pec", "eumc"]
        assert [t["controller"] for t in plans[1]] == ["pec", "umc", "eumc"]

        pec = next(t for t in plans[0] if t["controller"] == "pec")
        _ok(client.post("/api/worker/simulation", json={"seed": 22, "script": "squat-sequence"}))
        _wait_ticks(client)
        started = _ok(client.post(f"/api/trials/{pec['id']}/start", json={}))
        assert started["status"] == "running"
        assert started["config_snapshot"]["settings"]["pec_rate_hz"] == 100
        busy = client.post(f"/api/sessions/{dc['id']}/recordings", json={})
        assert busy.status_code == 409 and "still running" in busy.text
        _let_run(client, 30.0)  # 6 s of wall time at 5x
        stopped = _ok(client.post(f"/api/trials/{pec['id']}/stop",
                                  json={"outcome": "completed"}))
        assert stopped["status"] == "completed"
        events = _ok(client.get(f"/api/trials/{pec['id']}/lock-events"))
        assert any(e["kind"] == "command_on" for e in events)

        # The E-UMC refuses to start before a calibration.
        eumc = next(t for t in plans[0] if t["controller"] == "eumc")
        r = client.post(f"/api/trials/{eumc['id']}/start", json={})
        assert r.status_code == 409 and "calibration" in r.text

        # A timed trial that puts its simulated wearer on as it starts: exactly its
        # 20 s of the script from the first sample, at 100x; then the wearer goes on at
        # real time. A script the simulator does not know is a 422 that starts nothing.
        umc = next(t for t in plans[0] if t["controller"] == "umc")
        for body, field in (
                ({"duration_s": 20.0, "simulation": {"seed": 23, "script": "cartwheels"}},
                 ["body", "simulation", "script"]),
                ({"duration_s": 0.004}, ["body", "duration_s"])):  # under one sample
            bad = client.post(f"/api/trials/{umc['id']}/start", json=body)
            assert bad.status_code == 422, bad.text
            assert bad.json()["detail"][0]["loc"] == field
        assert _ok(client.get(f"/api/trials/{umc['id']}"))["status"] == "planned"
        timed = _ok(client.post(f"/api/trials/{umc['id']}/start", json={
            "duration_s": 20.0,
            "simulation": {"seed": 23, "script": "squat-sequence", "speed": 100}}))
        assert timed["config_snapshot"]["simulation"] == {
            "seed": 23, "script": "squat-sequence", "speed": 100.0}
        assert timed["config_snapshot"]["device"] == {
            "kind": "sim", "seed": 23, "script": "squat-sequence"}
        wait_for(lambda: past_run(client, timed["run_id"], 2000), 120,
                 "the end of the trial's 20 s", poll=0.1)
        assert ticks_per_second(client) < 2000  # at 100x: 10,000 a second
        # The speed asked for last (the trial's 100x) is the server's record too: the next
        # wearer put on without one takes it, as would a restarted worker.
        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        assert runtime.supervisor.config.device_speed == runtime.settings.device_speed == 100
        timed = _ok(client.post(f"/api/trials/{umc['id']}/stop", json={}))
        assert timed["tick_count"] == 2000
        t = _ok(client.get(f"/api/trials/{umc['id']}/ticks.json"))["columns"]["t"]
        assert t[0] == 0.0 and t[-1] == pytest.approx(19.99) and len(t) == 2000

        # A calibration is per wearer: made on a standing wearer, it serves an E-UMC
        # trial on that wearer, not one that puts another virtual participant on.
        _ok(client.post("/api/worker/simulation", json={"seed": 24, "script": "standing"}))
        _wait_ticks(client)
        assert _ok(client.post("/api/worker/calibrate", json={"seconds": 1.0}))["ok"]
        other = client.post(f"/api/trials/{eumc['id']}/start", json={
            "duration_s": 5.0, "simulation": {"seed": 25, "script": "squat-sequence"}})
        assert other.status_code == 409 and "calibration" in other.text
        bad = client.post(f"/api/trials/{eumc['id']}/start", json={  # refused: no change
            "rate_hz": 500, "simulation": {"seed": 25, "script": "squat-sequence"}})
        assert bad.status_code == 422, bad.text
        assert _ok(client.get(f"/api/trials/{eumc['id']}"))["status"] == "planned"
        mine = _ok(client.post(f"/api/trials/{eumc['id']}/start", json={
            "duration_s": 2.0, "simulation": {"seed": 24, "script": "standing", "speed": 50}}))
        assert mine["config_snapshot"]["settings"]["calibration"] is not None
        wait_for(lambda: past_run(client, mine["run_id"], 200), 120, "the E-UMC trial's 2 s",
                 poll=0.1)
        assert _ok(client.post(f"/api/trials/{eumc['id']}/stop", json={}))["tick_count"] == 200

        # 4. Export: one CSV row per stored tick, columns named by the data dictionary.
        text = client.get(f"/api/trials/{pec['id']}/ticks.csv").text
        rows = list(csv.DictReader(io.StringIO(text)))
        as_json = _ok(client.get(f"/api/trials/{pec['id']}/ticks.json"))["columns"]
        assert len(rows) == len(as_json["t"]) > 500
        assert any(r["lock_left"] == "1" for r in rows)
        assert float(rows[10]["t"]) == pytest.approx(as_json["t"][10])

        # 5. The whole study as a zip: what went in comes back out, unit for unit.
        r = client.get(f"/api/studies/{study['id']}/export.zip")
        assert r.status_code == 200
        zf = zipfile.ZipFile(io.BytesIO(r.content))
        names = set(zf.namelist())
        assert {"participants.csv", "trials.csv", "lift_segments.csv", "README.md",
                "data_dictionary.csv", f"ticks/trial-{pec['id']}.csv",
                f"model_sets/{ms['id']}.json", f"utility_sets/{us['id']}.json"} <= names
        people = list(csv.DictReader(io.StringIO(zf.read("participants.csv").decode())))
        assert [(p["code"], float(p["height_m"]), float(p["mass_kg"]), p["consent_date"])
                for p in people] == [("P01", 1.7, 65.0, "2026-11-20"),
                                     ("P02", 1.82, 80.0, "2026-11-21")]
        exported_ticks = zf.read(f"ticks/trial-{pec['id']}.csv").decode()
        assert exported_ticks == text
        segs = list(csv.DictReader(io.StringIO(zf.read("lift_segments.csv").decode())))
        assert len(segs) == len(segments)
        assert json.loads(zf.read(f"model_sets/{ms['id']}.json")) == doc

        # 6. Leave-one-participant-out needs a second participant's demonstrations. P02
        # only squats: P01's fold cannot be fitted (an error fold), P02's is scored.
        dc2 = _ok(client.post(f"/api/participants/{p2['id']}/sessions",
                              json={"kind": "data_collection", "precompression_pct": 25}), 201)
        rid2 = _record(client, dc2["id"], "squat-sequence", 35.0)
        theirs = _ok(client.post(f"/api/recordings/{rid2}/segment"))
        both = _ok(client.post(f"/api/studies/{study['id']}/model-sets",
                               json={"name": "P01+P02", "segment_ids": [
                                   s["id"] for s in segments + theirs]}), 202)
        assert _job(client, both["job_id"])["status"] == "done"
        lopo = _ok(client.get(f"/api/studies/{study['id']}/model-evaluation",
                              params={"model_set_id": both["id"], "utility_set_id": us["id"]}))
        assert lopo["participants"] == ["P01", "P02"]
        assert [f["participant"] for f in lopo["folds"]] == ["P01", "P02"]
        assert "too few training segments" in lopo["folds"][0]["error"]
        scored = [f for f in lopo["folds"] if "error" not in f]
        assert len(scored) == 1 and scored[0]["segments"] > 0
        assert lopo["segments"] == sum(f["segments"] for f in scored)
        assert set(lopo["recognition_confusion"]) == {"squat", "stoop_left", "stoop_right"}
        for matrix in (lopo["recognition_confusion"], lopo["decision_confusion"]):
            assert sum(sum(row.values()) for row in matrix.values()) == lopo["segments"]
        assert 0.0 <= lopo["recognition_accuracy"] <= 1.0
