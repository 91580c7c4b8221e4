"""Background jobs through the API: every job (cohorts included) at `GET /api/jobs/{id}`;
cohorts need the experimenter role and are limited per account; a utility table queued
behind two long cohorts finishes while they still run; a restart reconciles what a
killed server left and a shutdown cancels what runs; plans refuse sets that are not
ready, and a plan none of whose trials has started can be replaced."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import update

from backend.core.config import Settings
from backend.db.cohorts import CohortRecord
from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import Job, ModelSetRecord, Trial, UtilitySetRecord
from backend.main import create_app
from tests.login import bearer, create_experimenter, log_in
from tests.polling import wait_for

PASSWORD = "a long enough passphrase"
#: Long enough to still run while the rest of a test happens (minutes on this machine).
LONG = {"participants": 1000, "seed": 1, "controllers": ["umc", "eumc", "pec"]}


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def _rows(db_url: str, model: Any, *ids: int) -> list[Any]:
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        rows = [db.get(model, i) for i in ids]
        db.expunge_all()
    engine.dispose()
    return rows


def _write(db_url: str, *rows: Any) -> list[int]:
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        db.add_all(rows)
        db.commit()
        ids = [r.id for r in rows]
    engine.dispose()
    return ids


def _finished(client: TestClient, job_id: int, timeout: float) -> dict[str, Any]:
    """The job once it is final (done, failed or cancelled)."""
    def final() -> dict[str, Any]:
        job: dict[str, Any] = _ok(client.get(f"/api/jobs/{job_id}"))
        return job if job["status"] in ("done", "failed", "cancelled") else {}

    return wait_for(final, timeout, f"job {job_id} to finish", poll=0.1)


def _study_session(client: TestClient) -> tuple[int, int]:
    study = _ok(client.post("/api/studies", json={"name": "jobs"}), 201)
    part = _ok(client.post(f"/api/studies/{study['id']}/participants",
                           json={"code": "P01"}), 201)
    sess = _ok(client.post(f"/api/participants/{part['id']}/sessions",
                           json={"kind": "evaluation", "precompression_pct": 25}), 201)
    return study["id"], sess["id"]


def test_a_cohort_job_is_a_job_like_any_other(client: TestClient) -> None:
    cohort = _ok(client.post("/api/cohorts", json={"participants": 2, "seed": 3,
                                                   "controllers": ["umc"]}), 202)
    job = _ok(client.get(f"/api/jobs/{cohort['job_id']}"))
    assert job["kind"] == "cohort" and job["target_id"] == cohort["id"]
    assert job["lane"] == "cohort" and job["status"] in ("queued", "running", "done")
    done = _finished(client, cohort["job_id"], 300)
    assert done["status"] == "done", done["message"]
    assert done["progress"] == 1.0 and done["started_at"] and done["finished_at"]
    assert _ok(client.get(f"/api/cohorts/{cohort['id']}"))["status"] == "ready"


def test_cohorts_need_the_experimenter_role_somewhere(client: TestClient,
                                                      db_url: str) -> None:
    study_id, _ = _study_session(client)  # the admin's study
    for name in ("nora", "vic", "erin"):
        create_experimenter(db_url, name, PASSWORD)
    _ok(client.put(f"/api/studies/{study_id}/members",
                   json={"username": "vic", "role": "viewer"}))
    _ok(client.put(f"/api/studies/{study_id}/members",
                   json={"username": "erin", "role": "experimenter"}))
    other = TestClient(client.app)
    small = {"participants": 2, "controllers": ["umc"]}
    for name in ("nora", "vic"):
        h = bearer(other, {"username": name, "password": PASSWORD})
        r = other.post("/api/cohorts", json=small, headers=h)
        assert r.status_code == 403 and "experimenter" in r.text, r.text
        # Reading stays open to any login.
        assert other.get("/api/cohorts", headers=h).status_code == 200
    h = bearer(other, {"username": "erin", "password": PASSWORD})
    cohort = _ok(other.post("/api/cohorts", json=small, headers=h), 202)
    assert _ok(other.get(f"/api/jobs/{cohort['job_id']}", headers=h))["kind"] == "cohort"


def test_cohorts_are_limited_per_account_and_study_jobs_pass_them(
        settings: Settings, experimenter: dict[str, str], db_url: str) -> None:
    limited = settings.model_copy(update={"cohort_jobs_per_account": 2,
                                          "device_spawn_simulator": False})
    with TestClient(create_app(limited)) as client:
        log_in(client, experimenter)
        study_id, _ = _study_session(client)
        first, second = (_ok(client.post("/api/cohorts", json=LONG), 202) for _ in "12")
        r = client.post("/api/cohorts", json=LONG)
        assert r.status_code == 409, r.text
        assert "cohort_jobs_per_account" in r.text and "at most 2" in r.text
        us = _ok(client.post(f"/api/studies/{study_id}/utility-sets",
                             json={"name": "u", "precompression_pct": 25}), 202)
        done = _finished(client, us["job_id"], 120)
        assert done["status"] == "done", done["message"]
        # It did not wait for the cohorts: they are still unfinished.
        statuses = [_ok(client.get(f"/api/jobs/{c['job_id']}"))["status"]
                    for c in (first, second)]
        assert statuses == ["running", "queued"] or statuses == ["queued", "queued"]
        assert _ok(client.get(f"/api/utility-sets/{us['id']}"))["status"] == "ready"
    # Leaving the client shuts the server down: both cohorts are cancelled, with reason.
    jobs = _rows(db_url, Job, first["job_id"], second["job_id"])
    cohorts = _rows(db_url, CohortRecord, first["id"], second["id"])
    for job, cohort in zip(jobs, cohorts, strict=True):
        assert job.status == "cancelled" and "server shut down" in job.message
        assert cohort.status == "failed" and "server shut down" in cohort.error


def test_a_restart_ends_interrupted_jobs_and_their_sets(
        settings: Settings, experimenter: dict[str, str], db_url: str) -> None:
    quiet = settings.model_copy(update={"device_spawn_simulator": False})
    with TestClient(create_app(quiet)) as client:
        log_in(client, experimenter)
        study_id, session_id = _study_session(client)
    # What a SIGKILL leaves: sets and a cohort mid-way, their jobs running or queued.
    ms, us, cohort = _write(
        db_url, ModelSetRecord(study_id=study_id, name="m", status="fitting"),
        UtilitySetRecord(study_id=study_id, name="u", precompression_pct=25.0,
                         human_source="simulated", status="computing"),
        CohortRecord(config={}, status="running"))
    jobs = _write(db_url, Job(kind="fit_model_set", target_id=ms, status="running"),
                  Job(kind="compute_utilities", target_id=us, status="queued"),
                  Job(kind="cohort", target_id=cohort, status="running", lane="cohort"))
    with TestClient(create_app(quiet)) as client:
        log_in(client, experimenter)
        for job_id in jobs:
            job = _ok(client.get(f"/api/jobs/{job_id}"))
            assert job["status"] == "failed", job
            assert job["message"].startswith("interrupted by a server restart at ")
        for url in (f"/api/model-sets/{ms}", f"/api/utility-sets/{us}",
                    f"/api/cohorts/{cohort}"):
            got = _ok(client.get(url))
            assert got["status"] == "failed" and "server restart" in got["error"], got
        # The failed sets cannot be planned with: 409 naming the set and its state.
        r = client.post(f"/api/sessions/{session_id}/trials/plan",
                        json={"model_set_id": ms})
        assert r.status_code == 409 and f"model set {ms} is failed" in r.text, r.text
        assert _ok(client.get(f"/api/sessions/{session_id}/trials")) == []


def test_plans_need_ready_sets(client: TestClient, db_url: str) -> None:
    study_id, session_id = _study_session(client)
    ms, us = _write(db_url, ModelSetRecord(study_id=study_id, name="m", status="fitting"),
                    UtilitySetRecord(study_id=study_id, name="u", precompression_pct=25.0,
                                     human_source="simulated", status="computing"))
    url = f"/api/sessions/{session_id}/trials/plan"
    r = client.post(url, json={"model_set_id": ms})
    assert r.status_code == 409 and f"model set {ms} is fitting" in r.text, r.text
    r = client.post(url, json={"utility_set_id": us})
    assert r.status_code == 409 and f"utility set {us} is computing" in r.text, r.text
    assert _ok(client.get(f"/api/sessions/{session_id}/trials")) == []


def test_a_plan_is_replaced_only_on_request_and_only_before_a_trial_starts(
        client: TestClient, db_url: str) -> None:
    _, session_id = _study_session(client)
    url = f"/api/sessions/{session_id}/trials/plan"
    first = _ok(client.post(url, json={"tasks": ["walking"]}), 201)
    r = client.post(url, json={"tasks": ["walking"]})
    assert r.status_code == 409 and '"replace": true' in r.json()["detail"], r.text
    second = _ok(client.post(url, json={"tasks": ["walking", "stairs"], "replace": True}),
                 201)
    assert len(second) == 2 * len(first)
    listed = _ok(client.get(f"/api/sessions/{session_id}/trials"))
    assert [t["id"] for t in listed] == [t["id"] for t in second]
    assert {t["task"] for t in listed} == {"walking", "stairs"}
    # A trial that has run keeps the plan (and its data).
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        db.execute(update(Trial).where(Trial.id == second[0]["id"])
                   .values(status="completed"))
        db.commit()
    engine.dispose()
    r = client.post(url, json={"tasks": ["walking"], "replace": True})
    assert r.status_code == 409, r.text
    assert f"trial(s) {second[0]['id']} (completed)" in r.json()["detail"]
    kept = _ok(client.get(f"/api/sessions/{session_id}/trials"))
    assert [t["id"] for t in kept] == [t["id"] for t in second]
    assert kept[0]["status"] == "completed"


@pytest.mark.parametrize("status", ["failed", "fitting"])
def test_a_set_that_is_not_ready_names_itself(client: TestClient, db_url: str,
                                             status: str) -> None:
    study_id, session_id = _study_session(client)
    (ms,) = _write(db_url, ModelSetRecord(study_id=study_id, name="m", status=status,
                                          error="boom" if status == "failed" else ""))
    r = client.post(f"/api/sessions/{session_id}/trials/plan",
                    json={"model_set_id": ms, "tasks": ["walking"]})
    assert r.status_code == 409, r.text
    detail = r.json()["detail"]
    assert f"model set {ms} is {status}" in detail
    assert ("boom" in detail) == (status == "failed")
