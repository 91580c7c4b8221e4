"""Participants' rights and accounts: the cases of issue 13's "Why" as regression tests.

Cross-study actions by a second account, password policy and changes, disabled
accounts, throttling, the demo password on a non-loopback host, withdrawal (erase or
exclude), the de-identified export, consent versions, and single-use links under
parallel submission.
"""

from __future__ import annotations

import csv
import io
import zipfile
from concurrent.futures import ThreadPoolExecutor
from datetime import date

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.db.models import AuditEntry, LoginFailure, Participant, QuestionnaireResponse, User
from backend.main import create_app, refuse_published_passwords
from backend.study import accounts
from backend.study.password_policy import problem
from tests.login import bearer, create_experimenter

OTHER = {"username": "mallory", "password": "another long passphrase"}


def _study_with_participant(client: TestClient) -> int:
    assert client.post("/api/studies", json={"name": "mine"}).status_code == 201
    r = client.post("/api/studies/1/participants",
                    json={"code": "P01", "mass_kg": 81.3, "age": 34,
                          "consent_date": "2026-03-02", "notes": "lives next door"})
    assert r.status_code == 201, r.text
    pid: int = r.json()["id"]
    r = client.post(f"/api/participants/{pid}/conditions",
                    json={"label": "A", "controller": "umc"})
    assert r.status_code == 201, r.text
    return pid


def test_a_second_account_cannot_touch_another_experimenters_study(
        client: TestClient, db_url: str) -> None:
    pid = _study_with_participant(client)
    create_experimenter(db_url, **OTHER)
    h = bearer(TestClient(client.app), OTHER)
    other = TestClient(client.app)
    attempts = [
        ("PATCH", "/api/studies/1", {"name": "renamed"}),
        ("PATCH", f"/api/participants/{pid}", {"mass_kg": 200}),
        ("GET", f"/api/participants/{pid}/conditions", None),
        ("GET", "/api/audit", None),
        ("GET", "/api/studies/1/export.zip", None),
        ("GET", "/api/studies/1/export-deidentified.zip", None),
        ("GET", f"/api/participants/{pid}", None),
        ("GET", "/api/studies/1/participants", None),
        ("POST", f"/api/participants/{pid}/sessions",
         {"kind": "evaluation", "precompression_pct": 25}),
        ("POST", f"/api/participants/{pid}/withdraw", None),
        ("POST", "/api/worker/controller", {"controller": "pec"}),
        ("POST", "/api/worker/stop", None),
        ("GET", "/api/users", None),
        ("PUT", "/api/studies/1/members", {"username": "mallory", "role": "owner"}),
        ("POST", "/api/studies/1/consent", {"version": "2", "text": "x"}),
    ]
    for method, path, body in attempts:
        r = other.request(method, path, json=body, headers=h)
        assert r.status_code == 403, f"{method} {path}: {r.status_code} {r.text}"
    assert other.get("/api/studies", headers=h).json() == []
    assert client.get(f"/api/participants/{pid}").json()["mass_kg"] == 81.3
    assert client.get("/api/studies/1").json()["name"] == "mine"


@pytest.mark.parametrize("password", ["12345678", "        ", "password password",
                                      "123456789012345", "passwordpassword1",
                                      "aaaaaaaaaaaaaaaa", "qwertyuiopasdfgh",
                                      "exostudyexostudy", "experimenter2026!!"])
def test_the_policy_refuses_short_common_and_repetitive_passwords(password: str) -> None:
    assert problem(password, "experimenter") is not None


@pytest.mark.parametrize("password", ["correct horse battery staple",
                                      "a long passphrase", "Tr0ub4dor&3-but-longer"])
def test_the_policy_accepts_long_uncommon_passphrases(password: str) -> None:
    assert problem(password, "experimenter") is None


def test_password_change_ends_other_logins_and_disable_ends_all(
        client: TestClient, experimenter: dict[str, str], db_url: str) -> None:
    other_login = bearer(TestClient(client.app), experimenter)
    r = client.post("/api/auth/password", json={"current_password": "wrong one",
                                               "new_password": "a brand new passphrase"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "current_password"]
    r = client.post("/api/auth/password", json={"current_password": experimenter["password"],
                                               "new_password": "12345678"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "new_password"]
    r = client.post("/api/auth/password", json={"current_password": experimenter["password"],
                                               "new_password": "a brand new passphrase"})
    assert r.status_code == 204, r.text
    assert client.get("/api/auth/me").status_code == 200  # this login stays
    assert TestClient(client.app).get("/api/auth/me", headers=other_login).status_code == 401
    # An admin disables another account: its logins end at once.
    create_experimenter(db_url, **OTHER)
    h = bearer(TestClient(client.app), OTHER)
    uid = next(u["id"] for u in client.get("/api/users").json() if u["username"] == "mallory")
    assert client.patch(f"/api/users/{uid}", json={"active": False}).status_code == 200
    assert TestClient(client.app).get("/api/auth/me", headers=h).status_code == 401
    assert TestClient(client.app).post("/api/auth/token", json=OTHER).status_code == 401


def test_login_is_throttled_per_account_with_retry_after_and_audited(
        client: TestClient, experimenter: dict[str, str], db_url: str) -> None:
    anon = TestClient(client.app)
    wrong = {"username": experimenter["username"], "password": "not the password"}
    codes = [anon.post("/api/auth/token", json=wrong).status_code
             for _ in range(accounts.MAX_FAILURES_PER_ACCOUNT)]
    assert codes == [401] * accounts.MAX_FAILURES_PER_ACCOUNT
    r = anon.post("/api/auth/token", json=experimenter)  # even the right password waits
    assert r.status_code == 429
    wait = int(r.headers["retry-after"])
    assert 0 < wait <= accounts.THROTTLE_WINDOW.total_seconds() + 1
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        actions = list(db.scalars(select(AuditEntry.action)))
        failures = list(db.scalars(select(LoginFailure)))
    engine.dispose()
    assert actions.count("login_failed") == accounts.MAX_FAILURES_PER_ACCOUNT
    assert "login_throttled" in actions
    assert len(failures) == accounts.MAX_FAILURES_PER_ACCOUNT


def test_the_demo_password_refuses_a_network_host_and_is_announced(
        settings: Settings, db_url: str) -> None:
    from backend.db import migrate

    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    sessions = make_session_factory(engine)
    with sessions() as db:
        accounts.create_user(db, "demo", "exostudy-demo", "admin", published=True)
        db.commit()
    refuse_published_passwords(settings, sessions)  # 127.0.0.1: a warning only
    for host in ("0.0.0.0", "192.168.1.20", "exo.lab.example", "::"):
        with pytest.raises(RuntimeError, match="published demo password"):
            refuse_published_passwords(settings.model_copy(update={"host": host}), sessions)
    with TestClient(create_app(settings)) as c:
        h = bearer(c, {"username": "demo", "password": "exostudy-demo"})
        assert c.get("/api/auth/me", headers=h).json()["published_login_accounts"] == ["demo"]
    with sessions() as db:
        user = db.scalars(select(User).where(User.username == "demo")).one()
        accounts.change_password(db, user, "a private passphrase now")
        db.commit()
    refuse_published_passwords(settings.model_copy(update={"host": "0.0.0.0"}), sessions)
    engine.dispose()


def test_withdrawal_erases_everything_and_the_audit_keeps_no_data(
        client: TestClient, db_url: str) -> None:
    pid = _study_with_participant(client)
    r = client.post(f"/api/participants/{pid}/links",
                    json={"forms": [{"instrument_key": "sus", "condition_label": "A"}]})
    token = r.json()["token"]
    assert TestClient(client.app).post(
        f"/api/participant-forms/{token}/responses",
        json={"form": 0, "answers": {f"q{i}": 4 for i in range(1, 11)}}).status_code == 201
    r = client.post(f"/api/participants/{pid}/withdraw")
    assert r.status_code == 200 and r.json()["outcome"] == "erased"
    assert client.get(f"/api/participants/{pid}").status_code == 404
    engine = make_engine(db_url)
    with make_session_factory(engine)() as db:
        assert db.get(Participant, pid) is None
        assert list(db.scalars(select(QuestionnaireResponse))) == []
        entries = list(db.scalars(select(AuditEntry)))
    engine.dispose()
    text = repr([(e.details, e.entity_id) for e in entries])
    for secret in ("81.3", "lives next door", "2026-03-02", "34"):
        assert secret not in text, secret
    assert any(e.action == "withdraw" and e.details.get("outcome") == "erased" for e in entries)


def test_withdrawal_under_an_exclude_protocol_keeps_the_data_out_of_exports(
        client: TestClient) -> None:
    assert client.post("/api/studies", json={"name": "kept",
                                             "withdrawal_policy": "exclude"}).status_code == 201
    for code in ("P01", "P02"):
        assert client.post("/api/studies/1/participants", json={"code": code}).status_code == 201
    r = client.post("/api/participants/1/withdraw")
    assert r.json()["outcome"] == "excluded"
    assert client.get("/api/participants/1").json()["withdrawn_at"] is not None
    z = zipfile.ZipFile(io.BytesIO(client.get("/api/studies/1/export.zip").content))
    rows = list(csv.DictReader(io.StringIO(z.read("participants.csv").decode())))
    assert [r["code"] for r in rows] == ["P02"]


def test_the_deidentified_export_drops_identifiers_and_shifts_dates_per_participant(
        client: TestClient) -> None:
    assert client.post("/api/studies", json={"name": "share"}).status_code == 201
    for code, day, age in (("P01", "2026-03-02", 34), ("P02", "2026-03-02", 95)):
        r = client.post("/api/studies/1/participants", json={
            "code": code, "consent_date": day, "age": min(age, 100), "notes": "secret"})
        assert r.status_code == 201, r.text
        client.post(f"/api/participants/{r.json()['id']}/sessions",
                    json={"kind": "evaluation", "precompression_pct": 25, "notes": "secret"})
    r = client.get("/api/studies/1/export-deidentified.zip")
    assert r.status_code == 200
    z = zipfile.ZipFile(io.BytesIO(r.content))
    people = list(csv.DictReader(io.StringIO(z.read("participants.csv").decode())))
    sessions = list(csv.DictReader(io.StringIO(z.read("study_sessions.csv").decode())))
    assert sorted(p["code"] for p in people) == ["R001", "R002"]
    assert all(p["notes"] == "" for p in people)
    assert all(s["notes"] == "" for s in sessions)
    assert sorted(int(p["age"]) for p in people) == [34, 90]
    originals = client.get("/api/studies/1/participants").json()
    created = {p["id"]: p["created_at"][:10] for p in originals}
    for p in people:
        shifted = date.fromisoformat(p["consent_date"])
        days = (date(2026, 3, 2) - shifted).days
        assert 1 <= days <= 364
        # The same participant's other dates move by the same number of days.
        assert (date.fromisoformat(created[int(p["id"])])
                - date.fromisoformat(p["created_at"][:10])).days == days
        own = [s for s in sessions if s["participant_id"] == p["id"]]
        assert own and all(
            (date.fromisoformat(created[int(p["id"])]) -
             date.fromisoformat(s["started_at"][:10])).days in (days, days - 1, days + 1)
            for s in own)
    dictionary = list(csv.DictReader(io.StringIO(z.read("data_dictionary.csv").decode())))
    notes = {(d["file"], d["column"]): d["deidentified"] for d in dictionary}
    assert "pseudonym" in notes[("participants.csv", "code")]
    assert "shifted" in notes[("participants.csv", "consent_date")]
    assert notes[("participants.csv", "notes")].startswith("removed")
    assert "secret" not in r.content.decode("latin-1")


def test_consent_is_a_versioned_document_and_participants_record_theirs(
        client: TestClient) -> None:
    assert client.post("/api/studies", json={"name": "consent"}).status_code == 201
    r = client.post("/api/studies/1/consent", json={"version": "1.0", "text": "I agree."})
    assert r.status_code == 201
    assert client.post("/api/studies/1/consent",
                       json={"version": "1.0", "text": "changed"}).status_code == 409
    r = client.post("/api/studies/1/participants",
                    json={"code": "P01", "consent_version": "2.0"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "consent_version"]
    r = client.post("/api/studies/1/participants", json={
        "code": "P01", "consent_version": "1.0", "consent_date": "2026-01-05"})
    assert r.status_code == 201 and r.json()["consent_version"] == "1.0"
    assert [d["version"] for d in client.get("/api/studies/1/consent").json()] == ["1.0"]


def test_a_single_use_link_takes_one_answer_per_form_under_parallel_submissions(
        client: TestClient) -> None:
    pid = _study_with_participant(client)
    client.post(f"/api/participants/{pid}/conditions", json={"label": "B", "controller": "pec"})
    r = client.post(f"/api/participants/{pid}/links", json={
        "forms": [{"instrument_key": "sus", "condition_label": "A"}], "preference": True})
    assert r.status_code == 201, r.text
    token = r.json()["token"]
    anon = TestClient(client.app)

    def answer(v: int) -> int:
        return anon.post(f"/api/participant-forms/{token}/responses", json={
            "form": 0, "answers": {f"q{i}": v for i in range(1, 11)}}).status_code

    def prefer(choice: str) -> int:
        return anon.post(f"/api/participant-forms/{token}/preference",
                         json={"choice": choice}).status_code

    with ThreadPoolExecutor(8) as pool:
        codes = list(pool.map(answer, [1, 2, 3, 4, 5, 1, 2, 3]))
        prefs = list(pool.map(prefer, ["A", "B", "none", "A", "B", "none", "A", "B"]))
    assert codes.count(201) == 1 and set(codes) <= {201, 409, 410}
    assert prefs.count(201) == 1 and set(prefs) <= {201, 409, 410}
    assert len(client.get(f"/api/participants/{pid}/responses").json()) == 1
    assert len(client.get(f"/api/participants/{pid}/preferences").json()) == 1
