"""The role matrix, route by route: every operation in the OpenAPI schema is called by
an outsider, a viewer, an experimenter, an owner, an operator (an experimenter holding
the lab's device grant) and an admin, and answers 403 exactly when its rule
(`x-exostudy-access`) does not allow the role. The table in docs/access.md is
checked against the same schema."""

from __future__ import annotations

import csv
import io
import re
import zipfile
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import (
    Job,
    LiftSegment,
    ModelSetRecord,
    Recording,
    Trial,
    TrialSegment,
    UtilitySetRecord,
)
from backend.db.models import Participant, StudySession
from backend.db.personalisation import PriorSetRecord
from tests.login import PASSWORD as ADMIN_PASSWORD
from tests.login import USERNAME, bearer, create_experimenter

ROLES = ("outsider", "viewer", "experimenter", "owner", "operator", "admin")
#: Which callers each rule lets through (the outsider has an account, no membership;
#: the operator is an experimenter of study 1 to whom an admin gave the device grant;
#: the owner created study 1, which gives no device rights).
ALLOWED: dict[str, set[str]] = {
    "login": set(ROLES),
    "admin": {"admin"},
    "worker": {"experimenter", "owner", "operator", "admin"},
    "device": {"operator", "admin"},
    "viewer": {"viewer", "experimenter", "owner", "operator", "admin"},
    "experimenter": {"experimenter", "owner", "operator", "admin"},
    "owner": {"owner", "admin"},
}
#: Operations whose success would end the caller's login or erase the seeded rows:
#: only their refusals are checked here (tests/backend/study/test_data_protection.py
#: exercises them).
DESTRUCTIVE = {("post", "/api/auth/logout"), ("post", "/api/auth/revoke-all"),
               ("post", "/api/participants/{participant_id}/withdraw"),
               ("delete", "/api/studies/{study_id}/members/{username}"),
               ("delete", "/api/segments/{segment_id}"),
               ("patch", "/api/users/{user_id}"),
               # Granting would change what the next calls of the viewer may do.
               ("put", "/api/device-grants/{username}")}
PATH_VALUES = {"key": "sus", "version": "1.0", "table": "table1", "fmt": "csv",
               "name": "figure1", "username": "vera", "user_id": "2"}
#: The accounts playing each role (the admin is the `client` fixture's).
NAMES = {"outsider": "oscar", "viewer": "vera", "experimenter": "eric", "owner": "olga",
         "operator": "otto"}
PASSWORD = "a long enough passphrase"


def _operations(schema: dict[str, Any]) -> list[tuple[str, str, str]]:
    ops = []
    for path, item in schema["paths"].items():
        for method, op in item.items():
            if method in {"get", "post", "put", "patch", "delete"}:
                ops.append((method, path, op["x-exostudy-access"]))
    return ops


def _concrete(path: str) -> str:
    return re.sub(r"\{(\w+)\}", lambda m: PATH_VALUES.get(m.group(1), "1"), path)


def _seed_rows(db_url: str) -> None:
    """One row of every kind a path id can name, all in study 1."""
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        p = db.get(Participant, 1)
        assert p is not None
        s = StudySession(participant_id=p.id, kind="evaluation", precompression_pct=25.0)
        db.add(s)
        db.flush()
        rec = Recording(session_id=s.id, status="stopped")
        trial = Trial(session_id=s.id, controller="umc", task="walking", planned_order=0,
                      status="planned")
        ms = ModelSetRecord(study_id=1, name="m", status="failed")
        us = UtilitySetRecord(study_id=1, name="u", precompression_pct=25.0,
                              human_source="simulated", status="failed")
        db.add_all([rec, trial, ms, us])
        db.flush()
        db.add_all([LiftSegment(recording_id=rec.id, start=0, peak=1, end=2),
                     TrialSegment(trial_id=trial.id, start=0, peak=1, end=2),
                     Job(kind="fit_model_set", target_id=ms.id, status="failed"),
                     PriorSetRecord(study_id=1, participant_id=p.id, version=1, name="p",
                                    method="equal", status="ready")])
        db.commit()
    engine.dispose()


@pytest.fixture
def callers(client: TestClient, db_url: str) -> dict[str, dict[str, str]]:
    """Bearer headers of one account per role; study 1 belongs to `owner`."""
    app = client.app
    headers: dict[str, dict[str, str]] = {}
    for role in ("outsider", "viewer", "experimenter", "owner", "operator"):
        create_experimenter(db_url, NAMES[role], PASSWORD)
    creds = {r: {"username": NAMES[r], "password": PASSWORD} for r in NAMES}
    owner = TestClient(app)
    headers["owner"] = bearer(owner, creds["owner"])
    r = owner.post("/api/studies", json={"name": "matrix"}, headers=headers["owner"])
    assert r.status_code == 201, r.text
    for role, study_role in (("viewer", "viewer"), ("experimenter", "experimenter"),
                             ("operator", "experimenter")):
        r = owner.put("/api/studies/1/members",
                      json={"username": NAMES[role], "role": study_role},
                      headers=headers["owner"])
        assert r.status_code == 200, r.text
    r = owner.post("/api/studies/1/participants", json={"code": "P01"},
                   headers=headers["owner"])
    assert r.status_code == 201, r.text
    _seed_rows(db_url)
    for role in ("viewer", "experimenter", "outsider", "operator"):
        headers[role] = bearer(owner, creds[role])
    # The `client` fixture's account is the database's first, hence its admin.
    headers["admin"] = bearer(owner, {"username": USERNAME, "password": ADMIN_PASSWORD})
    r = owner.put(f"/api/device-grants/{NAMES['operator']}", headers=headers["admin"])
    assert r.status_code == 200, r.text
    return headers


def _bearer_client(client: TestClient) -> TestClient:
    """A client without the fixture's session cookie (each call carries a bearer token)
    whose requests run on the fixture client's event loop, as a server's would: a
    `TestClient` outside a `with` block starts a thread and an event loop for every
    request, 1 to 3 ms of CPU each, and the matrix makes about 900."""
    other = TestClient(client.app)
    other.portal = client.portal
    return other


def test_every_operation_refuses_exactly_the_roles_its_rule_excludes(
        client: TestClient, callers: dict[str, dict[str, str]]) -> None:
    schema = client.app.openapi()  # type: ignore[attr-defined]
    anyone = _bearer_client(client)
    checked = 0
    for method, path, rule in _operations(schema):
        if rule in ("public", "participant"):
            continue
        for role in ROLES:
            allowed = role in ALLOWED[rule]
            if allowed and (method, path) in DESTRUCTIVE:
                continue
            r = anyone.request(method.upper(), _concrete(path), json={},
                               headers=callers[role])
            where = f"{method.upper()} {path} ({rule}) as {role}: {r.status_code} {r.text[:200]}"
            if allowed:
                assert r.status_code not in (401, 403), where
                assert r.status_code < 500, where
            else:
                assert r.status_code == 403, where
            checked += 1
    assert checked >= 6 * 60


def test_a_site_limited_member_sees_and_reaches_only_their_site(
        client: TestClient, db_url: str) -> None:
    create_experimenter(db_url, "leuven", PASSWORD)
    client.post("/api/studies", json={"name": "two sites"})
    for code, site in (("L01", "Leuven"), ("G01", "Ghent")):
        r = client.post("/api/studies/1/participants", json={"code": code, "site": site})
        assert r.status_code == 201, r.text
    r = client.put("/api/studies/1/members",
                   json={"username": "leuven", "role": "experimenter", "site": "Leuven"})
    assert r.status_code == 200, r.text
    h = bearer(TestClient(client.app), {"username": "leuven", "password": PASSWORD})
    other = TestClient(client.app)
    listed = other.get("/api/studies/1/participants", headers=h).json()
    assert [p["code"] for p in listed] == ["L01"]
    assert other.get("/api/participants/1", headers=h).status_code == 200
    refused = other.get("/api/participants/2", headers=h)
    assert refused.status_code == 403 and "site" in refused.json()["detail"]
    assert other.patch("/api/participants/2", json={"mass_kg": 200},
                       headers=h).status_code == 403
    # Enrolling puts the participant in the member's own site, and no other.
    r = other.post("/api/studies/1/participants", json={"code": "L02"}, headers=h)
    assert r.status_code == 201 and r.json()["site"] == "Leuven"
    r = other.post("/api/studies/1/participants", json={"code": "G02", "site": "Ghent"},
                   headers=h)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "site"]


def test_the_documented_role_matrix_is_the_schema(client: TestClient) -> None:
    page = (Path(__file__).resolve().parents[3] / "docs" / "access.md").read_text()
    section = page.split("## Access and roles", 1)[1].split("\n## ", 1)[0]
    rows = dict(re.findall(r"^\| `(\w+ [^`]+)` \| (\w+) \|", section, re.M))
    schema = client.app.openapi()  # type: ignore[attr-defined]
    expected = {f"{m.upper()} {p}": rule for m, p, rule in _operations(schema)}
    assert rows == expected


def matrix_markdown(schema: dict[str, Any]) -> str:
    """The role matrix of docs/access.md, from the schema
    (`python -m tests.backend.api.test_roles`)."""
    columns = ("member", *ROLES[1:])
    lines = ["| operation | needs | " + " | ".join(columns) + " |",
             "|---|---|" + "---|" * len(columns)]
    for method, path, rule in _operations(schema):
        if rule in ("public", "participant"):
            cells = ["anyone" if rule == "public" else "link token"] + [""] * (len(columns) - 1)
        else:
            allowed = ALLOWED[rule] | ({"member"} if rule == "login" else set())
            cells = ["✓" if c in allowed else "" for c in columns]
        lines.append(f"| `{method.upper()} {path}` | {rule} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    from backend.core.config import Settings
    from backend.main import create_app

    app = create_app(Settings(_env_file=None, start_worker=False, demo=False))  # type: ignore[call-arg]
    print(matrix_markdown(app.openapi()), end="")


def test_only_owners_see_which_controller_a_label_stands_for(
        client: TestClient, callers: dict[str, dict[str, str]]) -> None:
    anyone = _bearer_client(client)
    r = anyone.post("/api/participants/1/conditions", json={"label": "A", "controller": "umc"},
                    headers=callers["owner"])
    assert r.status_code == 201, r.text
    seen = {role: anyone.get("/api/participants/1/conditions", headers=callers[role]).json()
            for role in ("viewer", "experimenter", "owner", "admin")}
    assert seen["owner"] == seen["admin"] and seen["owner"][0]["controller"] == "umc"
    for role in ("viewer", "experimenter"):
        assert [(c["label"], c["controller"]) for c in seen[role]] == [("A", None)]


def test_results_leave_out_other_sites_and_withdrawn_participants(
        client: TestClient, db_url: str) -> None:
    """The study's results use only what the caller may see, and never a participant
    who withdrew under an "exclude" protocol."""
    create_experimenter(db_url, "leuven", PASSWORD)
    assert client.post("/api/studies", json={
        "name": "two sites", "withdrawal_policy": "exclude"}).status_code == 201
    for code, site in (("L01", "Leuven"), ("G01", "Ghent"), ("L02", "Leuven")):
        r = client.post("/api/studies/1/participants", json={"code": code, "site": site})
        assert r.status_code == 201, r.text
        s = client.post(f"/api/participants/{r.json()['id']}/sessions",
                        json={"kind": "evaluation", "precompression_pct": 25})
        assert s.status_code == 201, s.text
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        for session_id in (1, 2, 3):  # one planned trial each, trial id = session id
            db.add(Trial(session_id=session_id, controller="pec", task="squat",
                         planned_order=1, status="planned"))
        db.commit()
    engine.dispose()

    def skipped(c: TestClient, headers: dict[str, str] | None = None) -> list[int]:
        r = c.get("/api/studies/1/results", headers=headers)
        assert r.status_code == 200, r.text
        return sorted(s["trial_id"] for s in r.json()["skipped"])

    assert skipped(client) == [1, 2, 3]
    assert client.put("/api/studies/1/members", json={
        "username": "leuven", "role": "experimenter", "site": "Leuven"}).status_code == 200
    h = bearer(TestClient(client.app), {"username": "leuven", "password": PASSWORD})
    assert skipped(TestClient(client.app), h) == [1, 3]
    assert client.post("/api/participants/3/withdraw").json()["outcome"] == "excluded"
    assert skipped(client) == [1, 2]
    assert skipped(TestClient(client.app), h) == [1]
    # The de-identified export follows the same rule (re-coded: count the rows).
    z = zipfile.ZipFile(io.BytesIO(TestClient(client.app).get(
        "/api/studies/1/export-deidentified.zip", headers=h).content))
    assert len(list(csv.DictReader(io.StringIO(z.read("participants.csv").decode())))) == 1
    z = zipfile.ZipFile(io.BytesIO(client.get("/api/studies/1/export-deidentified.zip").content))
    assert len(list(csv.DictReader(io.StringIO(z.read("participants.csv").decode())))) == 2
