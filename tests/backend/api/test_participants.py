"""Participants through the API: pseudonymous codes unique per study, plausible
ranges, corrections, and the blinding key."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import date, timedelta
from pathlib import Path
from uuid import uuid4

import pytest
from fastapi.testclient import TestClient

from tests.databases import AccountTemplates
from tests.module_client import logged_in_client, module_engines


@pytest.fixture
def study(client: TestClient) -> int:
    return int(client.post("/api/studies", json={"name": "S"}).json()["id"])


@pytest.fixture(scope="module", params=module_engines())
def reader(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory,
           default_sets: tuple[Path, Path], account_templates: AccountTemplates
           ) -> Iterator[TestClient]:
    """One logged-in app per engine for the refusals, which store nothing
    (`tests/module_client.py`); each of their tests makes its own study in it."""
    server = (request.getfixturevalue("postgres_cluster") if request.param == "postgresql"
              else None)
    with logged_in_client(tmp_path_factory.mktemp("participants"), default_sets,
                          account_templates, server) as c:
        yield c


def test_enrol_list_and_correct_a_participant(client: TestClient, study: int) -> None:
    body = {"code": "P01", "age": 28, "sex": "female", "height_m": 1.68, "mass_kg": 61.5,
            "consent_date": "2026-11-02", "notes": "right-handed"}
    r = client.post(f"/api/studies/{study}/participants", json=body)
    assert r.status_code == 201
    p = r.json()
    assert {k: p[k] for k in body} == body and p["study_id"] == study
    client.post(f"/api/studies/{study}/participants", json={"code": "P00"})
    codes = [x["code"] for x in client.get(f"/api/studies/{study}/participants").json()]
    assert codes == ["P00", "P01"]
    r = client.patch(f"/api/participants/{p['id']}", json={"mass_kg": 62.0, "sex": None})
    assert r.status_code == 200
    assert r.json()["mass_kg"] == 62.0 and r.json()["sex"] is None and r.json()["age"] == 28


def test_code_is_unique_within_a_study_only(client: TestClient, study: int) -> None:
    other = client.post("/api/studies", json={"name": "T"}).json()["id"]
    url = f"/api/studies/{study}/participants"
    assert client.post(url, json={"code": "P01"}).status_code == 201
    r = client.post(f"/api/studies/{study}/participants", json={"code": "P01"})
    assert r.status_code == 409 and r.json()["detail"].startswith("code:")
    r = client.post(f"/api/studies/{other}/participants", json={"code": "P01"})
    assert r.status_code == 201
    p2 = client.post(f"/api/studies/{study}/participants", json={"code": "P02"}).json()
    assert client.patch(f"/api/participants/{p2['id']}", json={"code": "P01"}).status_code == 409


@pytest.mark.parametrize(("field", "value"), [
    ("age", 12), ("age", 130), ("height_m", 178), ("mass_kg", 10), ("sex", "robot"),
    ("code", "Jane Doe"), ("code", ""),
    ("consent_date", (date.today() + timedelta(days=2)).isoformat()),
])
def test_implausible_values_are_422_naming_the_field(
    reader: TestClient, field: str, value: object
) -> None:
    # Study names are unique: one per test in the shared database.
    made = reader.post("/api/studies", json={"name": f"S {uuid4().hex}"})
    assert made.status_code == 201, made.text
    study = int(made.json()["id"])
    body = {"code": "P09", field: value}
    r = reader.post(f"/api/studies/{study}/participants", json=body)
    assert r.status_code == 422
    assert reader.get(f"/api/studies/{study}/participants").json() == []  # nothing stored
    assert r.json()["detail"][0]["loc"][:2] == ["body", field]


def test_unknown_ids_are_404(client: TestClient) -> None:
    assert client.post("/api/studies/77/participants", json={"code": "P1"}).status_code == 404
    assert client.get("/api/studies/77/participants").status_code == 404
    assert client.get("/api/participants/77").status_code == 404
    r = client.patch("/api/participants/77", json={"age": 30})
    assert r.status_code == 404 and "participant 77" in r.json()["detail"]


def test_blinding_key(client: TestClient, study: int) -> None:
    pid = client.post(f"/api/studies/{study}/participants", json={"code": "P01"}).json()["id"]
    url = f"/api/participants/{pid}/conditions"
    assert client.post(url, json={"label": "A", "controller": "umc"}).status_code == 201
    assert client.post(url, json={"label": "B", "controller": "pec"}).status_code == 201
    r = client.post(url, json={"label": "A", "controller": "eumc"})
    assert r.status_code == 409 and r.json()["detail"].startswith("label:")
    r = client.post(url, json={"label": "C", "controller": "umc"})
    assert r.status_code == 409 and r.json()["detail"].startswith("controller:")
    r = client.post(url, json={"label": "C", "controller": "telepathy"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "controller"]
    assert r.status_code == 422 and "telepathy" in r.json()["detail"][0]["msg"]
    assert client.post(url, json={"label": "a", "controller": "eumc"}).status_code == 422
    key = {c["label"]: c["controller"] for c in client.get(url).json()}
    assert key == {"A": "umc", "B": "pec"}
