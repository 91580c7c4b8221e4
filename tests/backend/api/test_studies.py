"""Studies through the API: create, list, read, rename; duplicates and unknown ids."""

from __future__ import annotations

from fastapi.testclient import TestClient


def test_create_list_get_and_rename_a_study(client: TestClient) -> None:
    r = client.post("/api/studies", json={"name": "Lifting 2026", "description": "UMC vs PEC"})
    assert r.status_code == 201
    study = r.json()
    assert study["name"] == "Lifting 2026" and study["created_by"] is not None
    assert study["created_at"].endswith("Z")
    assert client.get("/api/studies").json() == [study]
    assert client.get(f"/api/studies/{study['id']}").json() == study
    r = client.patch(f"/api/studies/{study['id']}", json={"name": "Lifting 2027"})
    assert r.status_code == 200 and r.json()["name"] == "Lifting 2027"
    assert r.json()["description"] == "UMC vs PEC"


def test_duplicate_name_is_409_and_names_the_field(client: TestClient) -> None:
    client.post("/api/studies", json={"name": "A"})
    other = client.post("/api/studies", json={"name": "B"}).json()
    r = client.post("/api/studies", json={"name": "A"})
    assert r.status_code == 409 and r.json()["detail"].startswith("name:")
    r = client.patch(f"/api/studies/{other['id']}", json={"name": "A"})
    assert r.status_code == 409
    assert client.patch(f"/api/studies/{other['id']}", json={"name": "B"}).status_code == 200


def test_unknown_study_is_404_and_bad_input_is_422(client: TestClient) -> None:
    r = client.get("/api/studies/999")
    assert r.status_code == 404 and "study 999" in r.json()["detail"]
    assert client.patch("/api/studies/999", json={"name": "x"}).status_code == 404
    r = client.post("/api/studies", json={"name": "   "})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "name"]
    r = client.post("/api/studies", json={"name": "ok", "colour": "red"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "colour"]
    r = client.post("/api/studies", json={"name": "nul\x00byte"})
    assert r.status_code == 422
    assert client.get("/api/studies/0").status_code == 422
    assert client.get(f"/api/studies/{2**63}").status_code == 422
