"""Logging in from tests: an experimenter account in a test database, and a login on a
TestClient (the session cookie stays in its cookie jar, the WebSocket sends it too)."""

from __future__ import annotations

from fastapi.testclient import TestClient

from backend.db import migrate
from backend.db.engine import make_engine, make_session_factory
from backend.study import accounts

USERNAME = "experimenter"
PASSWORD = "correct horse battery staple"


def create_experimenter(db_url: str, username: str = USERNAME,
                        password: str = PASSWORD) -> dict[str, str]:
    """Migrate the database and add an account; returns its login body."""
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    with make_session_factory(engine)() as session:
        accounts.create_user(session, username, password)
        session.commit()
    engine.dispose()
    return {"username": username, "password": password}


def log_in(client: TestClient, credentials: dict[str, str]) -> None:
    """Log the client in with the session cookie, and send what the pages send with
    every change: the same-origin `Origin` and the CSRF token of the login."""
    r = client.post("/api/auth/login", json=credentials)
    assert r.status_code == 200, r.text
    client.headers["Origin"] = str(client.base_url).rstrip("/")
    client.headers["X-CSRF-Token"] = r.cookies["exostudy_csrf"]


def bearer(client: TestClient, credentials: dict[str, str]) -> dict[str, str]:
    """Headers carrying a fresh bearer token."""
    r = client.post("/api/auth/token", json=credentials)
    assert r.status_code == 200, r.text
    return {"Authorization": f"Bearer {r.json()['access_token']}"}
