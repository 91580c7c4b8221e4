"""Sessions through the API: a participant's visits with the exoskeleton settings."""

from __future__ import annotations

from fastapi.testclient import TestClient


def _participant(client: TestClient) -> int:
    sid = client.post("/api/studies", json={"name": "S"}).json()["id"]
    return int(client.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"])


def test_sessions_of_a_participant(client: TestClient) -> None:
    pid = _participant(client)
    url = f"/api/participants/{pid}/sessions"
    r = client.post(url, json={"kind": "data_collection", "precompression_pct": 25,
                               "started_at": "2026-11-20T09:00:00+01:00"})
    assert r.status_code == 201
    first = r.json()
    assert first["started_at"] == "2026-11-20T08:00:00Z"
    second = client.post(url, json={"kind": "evaluation", "precompression_pct": 50}).json()
    assert [s["id"] for s in client.get(url).json()] == [first["id"], second["id"]]
    r = client.patch(f"/api/sessions/{second['id']}", json={"notes": "strap re-tightened"})
    assert r.json()["notes"] == "strap re-tightened" and r.json()["precompression_pct"] == 50
    assert client.get(f"/api/sessions/{first['id']}").json()["kind"] == "data_collection"


def test_session_validation_and_unknown_ids(client: TestClient) -> None:
    pid = _participant(client)
    url = f"/api/participants/{pid}/sessions"
    r = client.post(url, json={"kind": "party", "precompression_pct": 25})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "kind"]
    r = client.post(url, json={"kind": "evaluation", "precompression_pct": 120})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "precompression_pct"]
    assert client.post("/api/participants/99/sessions",
                       json={"kind": "evaluation", "precompression_pct": 25}).status_code == 404
    assert client.get("/api/sessions/99").status_code == 404
    assert client.patch("/api/sessions/99", json={"notes": ""}).status_code == 404
