"""The first start of a fresh installation creates the demo study; a database in use
never gets it."""

from __future__ import annotations

from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.main import create_app
from backend.study.demo import DEMO_PASSWORD, DEMO_USER
from tests.login import create_experimenter


def test_fresh_database_gets_a_demo_study_ready_for_an_eumc_trial(settings: Settings) -> None:
    with TestClient(create_app(settings.model_copy(update={"demo": True}))) as client:
        r = client.post("/api/auth/login", json={"username": DEMO_USER,
                                                 "password": DEMO_PASSWORD})
        assert r.status_code == 200
        studies = client.get("/api/studies").json()
        assert len(studies) == 1
        sid = studies[0]["id"]
        people = client.get(f"/api/studies/{sid}/participants").json()
        assert [p["code"] for p in people] == [f"V{i:02d}" for i in range(1, 8)]
        ms = client.get(f"/api/studies/{sid}/model-sets").json()
        us = client.get(f"/api/studies/{sid}/utility-sets").json()
        assert ms[0]["status"] == "ready" and us[0]["status"] == "ready"
        sess = client.get(f"/api/participants/{people[-1]['id']}/sessions").json()[0]
        trials = client.get(f"/api/sessions/{sess['id']}/trials").json()
        assert {t["controller"] for t in trials} == {"umc", "pec", "eumc"}
        assert trials[-1]["controller"] == "eumc"


def test_a_database_with_an_account_gets_no_demo(settings: Settings) -> None:
    create_experimenter(settings.database_url)
    with TestClient(create_app(settings.model_copy(update={"demo": True}))) as client:
        r = client.post("/api/auth/login", json={"username": DEMO_USER,
                                                 "password": DEMO_PASSWORD})
        assert r.status_code == 401
