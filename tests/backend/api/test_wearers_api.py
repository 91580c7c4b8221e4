"""Long use and the per-wearer progress through the API: refusals with a clear 4xx, and
the learning curves of three seeded real-study sessions checked against hand counts."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import event, select
from sqlalchemy.orm import Session

from backend.db.engine import make_engine
from backend.db.evidence_tables import ModelSetRecord, Trial
from backend.schemas.wearers import LONG_USE_TASK
from tests.backend.long_use_data import add_long_use_trial


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def _wearer(client: TestClient, kind: str = "long_use") -> tuple[int, int, int]:
    study = _ok(client.post("/api/studies", json={"name": f"Long use {kind}"}), 201)["id"]
    pid = _ok(client.post(f"/api/studies/{study}/participants", json={"code": "W01"}),
              201)["id"]
    sid = _ok(client.post(f"/api/participants/{pid}/sessions",
                          json={"kind": kind, "precompression_pct": 25}), 201)["id"]
    return study, pid, sid


def _detail(r: Any, code: int) -> str:
    assert r.status_code == code, r.text
    return str(r.json()["detail"])


def test_long_use_refusals_name_what_is_wrong(client: TestClient, db_url: str) -> None:
    study, _, sid = _wearer(client)
    _, _, evaluation = _wearer(client, "evaluation")
    url = f"/api/sessions/{sid}/long-use"
    assert "long_use" in _detail(client.post(f"/api/sessions/{evaluation}/long-use",
                                             json={"controller": "pec"}), 409)
    detail = _detail(client.post(url, json={"controller": "springs_free"}), 422)
    assert "controller" in detail and "umc" in detail
    assert "controller" in _detail(client.post(url, json={"controller": "none"}), 422)
    assert "model_set_id" in _detail(client.post(url, json={"controller": "umc"}), 422)
    assert "model_set_id" in _detail(client.post(url, json={
        "controller": "umc", "model_set_id": 999, "utility_set_id": 999}), 422)
    assert "rate_hz" in _detail(client.post(url, json={"controller": "pec",
                                                       "rate_hz": 0}), 422)
    assert "extra" in _detail(client.post(url, json={"controller": "pec", "x": 1}), 422)
    # Under one 10 ms sample times nothing: refused where it is asked, not at the trial.
    short = client.post(url, json={"controller": "pec", "duration_s": 0.001})
    assert short.status_code == 422 and short.json()["detail"][0]["loc"] == [
        "body", "duration_s"]
    assert client.post("/api/sessions/999999/long-use",
                       json={"controller": "pec"}).status_code == 404
    assert client.post("/api/sessions/0/long-use", json={"controller": "pec"}
                       ).status_code == 422
    # A pending model set of the study is refused as not ready (409), not started.
    engine = make_engine(db_url)
    with Session(engine) as db:
        ms = ModelSetRecord(study_id=study, name="fitting", status="pending")
        db.add(ms)
        db.commit()
        ms_id = ms.id
    assert "not ready" in _detail(client.post(url, json={
        "controller": "umc", "model_set_id": ms_id, "utility_set_id": ms_id}), 409)
    # No worker here: the start is refused and leaves no trial behind.
    assert "worker" in _detail(client.post(url, json={"controller": "pec"}), 409)
    with Session(engine) as db:
        assert list(db.scalars(select(Trial).where(Trial.session_id == sid))) == []
    # A long-use session takes no trial plan.
    assert "long_use" in _detail(client.post(f"/api/sessions/{sid}/trials/plan", json={}),
                                 409)


def test_progress_refusals(client: TestClient) -> None:
    _, pid, _ = _wearer(client)
    assert client.get("/api/participants/999999/progress").status_code == 404
    assert client.get("/api/participants/0/progress").status_code == 422
    detail = _detail(client.get(f"/api/participants/{pid}/progress",
                                params={"controller": "nonesuch"}), 422)
    assert "controller" in detail and "nonesuch" in detail
    # No use yet: no sessions, every curve empty.
    doc = _ok(client.get(f"/api/participants/{pid}/progress"))
    assert doc["sessions"] == [] and {c["trend"]["n"] for c in doc["curves"]} == {0}


def test_progress_of_three_sessions_matches_the_hand_counts(client: TestClient,
                                                            db_url: str) -> None:
    study, pid, _ = _wearer(client, "evaluation")
    engine = make_engine(db_url)
    # Created out of order: the curve follows the sessions' start, not their ids.
    days = (3, 1, 2)
    ids = {d: _ok(client.post(f"/api/participants/{pid}/sessions", json={
        "kind": "long_use", "precompression_pct": 25,
        "started_at": f"2026-12-0{d}T09:00:00Z"}), 201)["id"] for d in days}
    sessions = [ids[1], ids[2], ids[3]]
    seeded = [add_long_use_trial(engine, s, correct, 5 - correct, locks)
              for s, correct, locks in zip(sessions, (2, 3, 4), (3, 2, 1), strict=True)]
    doc = _ok(client.get(f"/api/participants/{pid}/progress"))
    assert [s["session_id"] for s in doc["sessions"]] == sessions
    for s, seed in zip(doc["sessions"], seeded, strict=True):
        assert s["trial_ids"] == [seed.trial_id] and s["truth"] == ["segments"]
        assert s["confirmed_lifts"] == 5 and s["unconfirmed_lifts"] == 1 and s["lifts"] == 6
        assert s["recognised"] == seed.correct and s["correct_locks"] == seed.correct
        assert s["walking_fp"] == seed.walking_locks and s["stairs_hours"] == 0
        assert s["hours"] == pytest.approx(seed.hours)
        assert s["walking_hours"] == pytest.approx(seed.walking_hours)
    curves = {c["metric"]: c for c in doc["curves"]}
    lock = curves["lock_rate"]
    assert [p["value"] for p in lock["points"]] == pytest.approx([0.4, 0.6, 0.8])
    assert lock["trend"]["slope"] == pytest.approx(0.2)
    assert lock["trend"]["low"] == pytest.approx(0.2) == lock["trend"]["high"]
    assert [p["n"] for p in lock["points"]] == [5, 5, 5]
    assert curves["recognition_rate"]["trend"]["slope"] == pytest.approx(0.2)
    # Every correct lock is held 0.3 s after onset: a flat curve, slope 0 inside [0, 0].
    ttl = curves["time_to_lock_s"]
    assert [p["value"] for p in ttl["points"]] == pytest.approx([0.3, 0.3, 0.3])
    assert ttl["trend"]["slope"] == pytest.approx(0.0, abs=1e-12)
    walk = curves["fp_per_hour_walking"]
    hours = seeded[0].walking_hours
    assert [p["value"] for p in walk["points"]] == pytest.approx([3 / hours, 2 / hours,
                                                                  1 / hours])
    assert walk["trend"]["slope"] == pytest.approx(-1 / hours)
    assert all(p["low"] <= p["value"] <= p["high"] for p in walk["points"])
    assert [p["value"] for p in curves["lifts_per_hour"]["points"]] == pytest.approx(
        [6 / seeded[0].hours] * 3)
    assert curves["fp_per_hour_stairs"]["trend"]["n"] == 0

    # Long-use trials are no plan's condition: the study's results leave them out.
    res = _ok(client.get(f"/api/studies/{study}/results"))
    assert res["trials"] == []
    assert {s["trial_id"] for s in res["skipped"]} == {t.trial_id for t in seeded}
    # Another controller's sessions only: none here.
    only_pec = _ok(client.get(f"/api/participants/{pid}/progress",
                              params={"controller": "pec"}))
    assert only_pec["sessions"] == [] and only_pec["controller"] == "pec"
    assert LONG_USE_TASK == "long_use"


def test_progress_uses_one_connection_and_the_tick_writer_has_its_own_pool(
        client: TestClient, db_url: str) -> None:
    """A progress request holds one pooled connection (its session's), never a second
    while holding the first; the tick writer draws from a pool of its own."""
    app: Any = client.app
    _, pid, sid = _wearer(client)
    add_long_use_trial(make_engine(db_url), sid, 2, 1, 1)
    out = {"now": 0, "most": 0}
    lock = threading.Lock()

    def checkout(*_: Any) -> None:
        with lock:
            out["now"] += 1
            out["most"] = max(out["most"], out["now"])

    def checkin(*_: Any) -> None:
        with lock:
            out["now"] -= 1

    pool = app.state.engine.pool
    event.listen(pool, "checkout", checkout)
    event.listen(pool, "checkin", checkin)
    try:
        doc = _ok(client.get(f"/api/participants/{pid}/progress"))
    finally:
        event.remove(pool, "checkout", checkout)
        event.remove(pool, "checkin", checkin)
    assert doc["sessions"][0]["confirmed_lifts"] == 3
    assert out["most"] == 1
    writer = app.state.runtime.recorder.engine
    assert writer is not app.state.engine and writer.pool is not pool


def test_twenty_progress_requests_at_once_all_answer(client: TestClient,
                                                      db_url: str) -> None:
    """More requests at once than the pool has connections: each waits for one
    connection and answers (two per request deadlocked the pool into 500s)."""
    _, pid, sid = _wearer(client)
    add_long_use_trial(make_engine(db_url), sid, 2, 1, 1)
    n = 20
    barrier = threading.Barrier(n)

    def ask(_: int) -> int:
        barrier.wait()
        return int(client.get(f"/api/participants/{pid}/progress").status_code)

    with ThreadPoolExecutor(n) as pool:
        codes = list(pool.map(ask, range(n)))
    assert codes == [200] * n


def test_long_use_refuses_another_wearers_personal_model_set(client: TestClient,
                                                              db_url: str) -> None:
    study, _, sid = _wearer(client)
    other = _ok(client.post(f"/api/studies/{study}/participants", json={"code": "W02"}),
                201)["id"]
    engine = make_engine(db_url)
    with Session(engine) as db:
        ms = ModelSetRecord(study_id=study, name="W02 personal", status="ready",
                            kind="personal", participant_id=other, document={"x": 1})
        db.add(ms)
        db.commit()
        ms_id = ms.id
    engine.dispose()
    r = client.post(f"/api/sessions/{sid}/long-use", json={
        "controller": "umc", "model_set_id": ms_id, "utility_set_id": ms_id})
    detail = _detail(r, 422)
    assert "another participant" in detail and "W01" in detail
    assert r.json()["detail"][0]["loc"] == ["body", "model_set_id"]
