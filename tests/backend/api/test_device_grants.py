"""Device rights come from the lab's grant, not from a study (backend/study/
device_grants.py): an account that creates a study cannot pulse a solenoid, switch
the controller or start a trial until an administrator grants it; revoking takes it
back; the command line does the same; every change is audited. And the bring-up
bodies take their safety confirmation as JSON true only."""

from __future__ import annotations

import io

import pytest
from fastapi.testclient import TestClient

from backend import cli
from backend.study.device_grants import MISSING
from tests.login import bearer, create_experimenter

PASSWORD = "a long enough passphrase"
Call = tuple[str, str, dict[str, object]]
DEVICE_CALLS: tuple[Call, ...] = (
                ("POST", "/api/worker/controller", {"name": "none"}),
                ("POST", "/api/hardware/pulse", {"side": "left", "nobody_wearing": True}),
                ("POST", "/api/hardware/release", {"side": "left", "nobody_wearing": True}),
                ("POST", "/api/hardware/profile", {}))


def _codes(c: TestClient, h: dict[str, str]) -> list[int]:
    return [c.request(m, p, json=b, headers=h).status_code for m, p, b in DEVICE_CALLS]


def test_creating_a_study_gives_no_device_rights_until_an_admin_grants_them(
        client: TestClient, db_url: str) -> None:
    create_experimenter(db_url, "olga", PASSWORD)
    other = TestClient(client.app)
    h = bearer(other, {"username": "olga", "password": PASSWORD})
    assert other.post("/api/studies", json={"name": "mine"}, headers=h).status_code == 201
    r = other.post("/api/worker/controller", json={"name": "pec"}, headers=h)
    assert r.status_code == 403 and r.json()["detail"] == MISSING
    assert "administrator" in MISSING and "study role does not include it" in MISSING
    assert set(_codes(other, h)) == {403}
    # Her own study's trial: owner of the study, still no device.
    part = other.post("/api/studies/1/participants", json={"code": "P1"}, headers=h).json()
    other.post(f"/api/participants/{part['id']}/sessions",
               json={"kind": "evaluation", "precompression_pct": 25}, headers=h)
    assert other.post("/api/trials/1/start", json={}, headers=h).status_code in (403, 404)

    # Only an admin grants (the `client` account is the database's first: admin).
    assert other.put("/api/device-grants/olga", headers=h).status_code == 403
    g = client.put("/api/device-grants/olga")
    assert g.status_code == 200 and g.json()["username"] == "olga"
    assert g.json()["granted_by"] == "experimenter"
    assert [x["username"] for x in client.get("/api/device-grants").json()] == ["olga"]
    assert 403 not in _codes(other, h)  # the worker is not running: 409s, not refusals
    # Revoked: refused again; a second revocation is a 404 that says so.
    assert client.delete("/api/device-grants/olga").status_code == 204
    assert set(_codes(other, h)) == {403}
    again = client.delete("/api/device-grants/olga")
    assert again.status_code == 404 and "device grant of olga" in again.text
    assert client.put("/api/device-grants/nobody").status_code == 404
    actions = [e["action"] for e in client.get("/api/audit").json()
               if e["action"] in ("grant_device", "revoke_device")]
    assert actions.count("grant_device") == 1 and actions.count("revoke_device") == 1


def test_the_command_line_grants_and_revokes(
        client: TestClient, db_url: str, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    create_experimenter(db_url, "eric", PASSWORD)
    monkeypatch.setenv("EXOSTUDY_DATABASE_URL", db_url)
    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    assert cli.main(["user", "grant-device", "eric"]) == 0
    assert "'eric' may use the exoskeleton" in capsys.readouterr().out
    assert [x["username"] for x in client.get("/api/device-grants").json()] == ["eric"]
    assert cli.main(["user", "revoke-device", "eric"]) == 0
    assert "no longer" in capsys.readouterr().out
    assert cli.main(["user", "revoke-device", "eric"]) == 0
    assert "held no device grant" in capsys.readouterr().out
    assert cli.main(["user", "grant-device", "nobody"]) == 2
    assert "no account named 'nobody'" in capsys.readouterr().err
    assert client.get("/api/device-grants").json() == []


def test_nobody_wearing_takes_only_json_true_or_false(client: TestClient) -> None:
    for path in ("pulse", "watchdog", "release"):
        for value in ("yes", "on", "1", "true", 1, 1.0, 0, None):
            r = client.post(f"/api/hardware/{path}",
                            json={"side": "left", "nobody_wearing": value})
            assert r.status_code == 422, (path, value, r.text)
            (problem,) = r.json()["detail"]
            assert problem["loc"] == ["body", "nobody_wearing"]
            assert f"must be JSON true or false, not {value!r}" in problem["msg"]
