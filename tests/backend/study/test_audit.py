"""The audit log: every write leaves an entry naming who did it, in the same
transaction, so a write that fails half-way leaves neither the change nor the entry."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from backend.db import audit
from tests.login import USERNAME


def test_writes_are_audited_with_who_and_what(client: TestClient) -> None:
    sid = client.post("/api/studies", json={"name": "Audit"}).json()["id"]
    pid = client.post(f"/api/studies/{sid}/participants",
                      json={"code": "P1", "age": 40}).json()["id"]
    client.patch(f"/api/participants/{pid}", json={"age": 41})
    entries = client.get("/api/audit").json()
    assert [(e["action"], e["entity"]) for e in entries[:3]] == [
        ("update", "participant"), ("create", "participant"), ("create", "study")]
    assert all(e["actor"] == USERNAME and e["user_id"] for e in entries[:3])
    assert entries[0]["details"] == {"before": {"age": 40}, "after": {"age": 41}}
    only = client.get("/api/audit", params={"entity": "participant", "entity_id": str(pid)})
    assert [e["action"] for e in only.json()] == ["update", "create"]
    assert len(client.get("/api/audit", params={"limit": 1}).json()) == 1
    assert client.get("/api/audit", params={"limit": 0}).status_code == 422


def test_participant_submissions_are_audited_without_a_user(client: TestClient) -> None:
    sid = client.post("/api/studies", json={"name": "Audit"}).json()["id"]
    pid = client.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"]
    client.post(f"/api/participants/{pid}/conditions", json={"label": "A", "controller": "umc"})
    link = client.post(f"/api/participants/{pid}/links", json={"preference": True}).json()
    TestClient(client.app).post(f"/api/participant-forms/{link['token']}/preference",
                                json={"choice": "A"})
    last = client.get("/api/audit").json()[0]
    assert last["actor"] == f"participant link {link['id']}" and last["user_id"] is None


def test_a_failed_write_leaves_nothing_behind(client: TestClient,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    sid = client.post("/api/studies", json={"name": "Tx"}).json()["id"]
    before = client.get("/api/audit").json()

    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("disk full while auditing")

    monkeypatch.setattr(audit, "record", broken)
    with pytest.raises(RuntimeError):
        client.post(f"/api/studies/{sid}/participants", json={"code": "P1"})
    monkeypatch.undo()
    assert client.get(f"/api/studies/{sid}/participants").json() == []
    assert client.get("/api/audit").json() == before
