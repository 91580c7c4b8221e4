"""Logging in: cookie and bearer token, `me`, logout, refused credentials, expiry, and
the `exostudy user add` command."""

from __future__ import annotations

import io
from datetime import UTC, datetime, timedelta

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select, update

from backend import cli
from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.db.models import AuditEntry, AuthToken, User
from backend.main import create_app
from tests.login import PASSWORD, USERNAME, bearer, log_in


def test_login_sets_an_httponly_cookie_and_me_answers(
    settings: Settings, experimenter: dict[str, str]
) -> None:
    with TestClient(create_app(settings)) as client:
        assert client.get("/api/auth/me").status_code == 401
        r = client.post("/api/auth/login", json=experimenter)
        assert r.status_code == 200
        cookie = r.headers["set-cookie"].lower()
        assert "exostudy_session=" in cookie and "httponly" in cookie
        assert "samesite=strict" in cookie
        assert r.json()["user"]["username"] == USERNAME
        assert "password" not in r.text and "hash" not in r.text
        me = client.get("/api/auth/me")
        assert me.status_code == 200 and me.json()["username"] == USERNAME


def test_wrong_password_and_unknown_user_get_the_same_401(
    settings: Settings, experimenter: dict[str, str]
) -> None:
    with TestClient(create_app(settings)) as client:
        wrong = client.post("/api/auth/login", json={"username": USERNAME, "password": "nope"})
        nobody = client.post("/api/auth/login", json={"username": "ghost", "password": "x"})
        assert wrong.status_code == nobody.status_code == 401
        assert wrong.json() == nobody.json()
        assert client.get("/api/studies").status_code == 401
        missing = client.post("/api/auth/login", json={"username": USERNAME})
        assert missing.status_code == 422
        assert missing.json()["detail"][0]["loc"] == ["body", "password"]


def test_bearer_token_for_scripts_and_logout_revokes_only_that_login(
    settings: Settings, experimenter: dict[str, str]
) -> None:
    app = create_app(settings)
    with TestClient(app) as script, TestClient(app) as browser:
        headers = bearer(script, experimenter)
        log_in(browser, experimenter)
        assert script.get("/api/studies", headers=headers).status_code == 200
        assert script.get("/api/studies").status_code == 401  # no cookie in this client
        assert script.post("/api/auth/logout", headers=headers).status_code == 204
        assert script.get("/api/studies", headers=headers).status_code == 401
        assert browser.get("/api/studies").status_code == 200
        assert browser.post("/api/auth/logout").status_code == 204
        assert browser.get("/api/studies").status_code == 401
        bad = script.get("/api/studies", headers={"Authorization": "Bearer not-a-token"})
        assert bad.status_code == 401 and bad.headers["www-authenticate"] == "Bearer"


def test_expired_login_and_disabled_account_are_refused(
    settings: Settings, experimenter: dict[str, str]
) -> None:
    engine = make_engine(settings.database_url)
    with TestClient(create_app(settings)) as client:
        headers = bearer(client, experimenter)
        with engine.begin() as conn:
            conn.execute(update(AuthToken).values(
                expires_at=datetime.now(UTC) - timedelta(seconds=1)))
        assert client.get("/api/auth/me", headers=headers).status_code == 401
        headers = bearer(client, experimenter)
        with engine.begin() as conn:
            conn.execute(update(User).values(active=False))
        assert client.get("/api/auth/me", headers=headers).status_code == 401
        assert client.post("/api/auth/token", json=experimenter).status_code == 401
    engine.dispose()


def test_only_a_hash_of_password_and_token_is_stored(
    settings: Settings, experimenter: dict[str, str]
) -> None:
    with TestClient(create_app(settings)) as client:
        token = client.post("/api/auth/token", json=experimenter).json()["access_token"]
    engine = make_engine(settings.database_url)
    with make_session_factory(engine)() as db:
        user = db.scalars(select(User)).one()
        assert user.password_hash.startswith("$argon2id$") and PASSWORD not in user.password_hash
        hashes = [t.token_hash for t in db.scalars(select(AuthToken))]
        assert token not in hashes and len(hashes) == 1
        logins = db.scalars(select(AuditEntry).where(AuditEntry.action == "login")).all()
        assert [a.actor for a in logins] == [USERNAME]
    engine.dispose()


def test_cli_user_add_reads_the_password_from_stdin(
    db_url: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
    settings: Settings,
) -> None:
    monkeypatch.setenv("EXOSTUDY_DATABASE_URL", db_url)
    monkeypatch.setattr("sys.stdin", io.StringIO("a long passphrase\n"))
    assert cli.main(["user", "add", "maria"]) == 0
    assert "maria" in capsys.readouterr().out
    monkeypatch.setattr("sys.stdin", io.StringIO("another one here\n"))
    assert cli.main(["user", "add", "maria"]) == 2
    assert "already exists" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin", io.StringIO("short\n"))
    assert cli.main(["user", "add", "jo"]) == 2
    assert "at least 15" in capsys.readouterr().err
    assert cli.main(["user", "list"]) == 0
    assert capsys.readouterr().out.split() == ["maria", "admin", "active"]
    with TestClient(create_app(settings)) as client:
        r = client.post("/api/auth/login",
                        json={"username": "maria", "password": "a long passphrase"})
        assert r.status_code == 200
