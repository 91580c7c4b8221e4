"""WebSockets end with their login (issue 23: /ws/live kept streaming after logout):
logout, "log out everywhere" and disabling the account each close the socket with 1008;
a binary frame closes it with 1003 and one log line; health counts open connections
only."""

from __future__ import annotations

import logging
import threading
from typing import Any

import pytest
from fastapi.testclient import TestClient
from starlette.testclient import WebSocketTestSession

from backend.db.engine import make_engine, make_session_factory
from backend.study import accounts
from tests.login import log_in
from tests.polling import wait_for


class _Closes:
    """Reads a socket on a thread until the server closes it; `code` is its close code."""

    def __init__(self, ws: WebSocketTestSession) -> None:
        self.code: int | None = None
        self.reason = ""
        self.messages = 0
        self._ws = ws
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        while True:
            message = self._ws.receive()
            if message["type"] == "websocket.close":
                self.code, self.reason = message.get("code", 1000), message.get("reason", "")
                return
            self.messages += 1


def _open(client: TestClient) -> tuple[Any, _Closes]:
    cm = client.websocket_connect("/ws/live")
    ws = cm.__enter__()
    assert ws.receive_json()["type"] == "status"
    return cm, _Closes(ws)


def _closed(client: TestClient, closes: _Closes) -> None:
    wait_for(lambda: closes.code is not None, 15, "the server to close the socket")
    assert closes.code == 1008
    wait_for(lambda: client.app.state.socket_logins.open_count == 0, 15,  # type: ignore[attr-defined]
             "the watcher to end")


def test_logout_closes_the_live_socket(client: TestClient) -> None:
    cm, closes = _open(client)
    assert client.post("/api/auth/logout").status_code == 204
    _closed(client, closes)
    assert closes.reason == "logged out"
    cm.__exit__(None, None, None)


def test_revoke_all_closes_the_live_socket(client: TestClient,
                                           experimenter: dict[str, str]) -> None:
    other = TestClient(client.app)
    log_in(other, experimenter)  # a second login of the same account
    cm, closes = _open(client)
    assert other.post("/api/auth/revoke-all").status_code == 204
    _closed(client, closes)
    cm.__exit__(None, None, None)


def test_disabling_the_account_closes_its_live_socket(client: TestClient) -> None:
    engine = make_engine(str(client.app.state.settings.database_url))  # type: ignore[attr-defined]
    with make_session_factory(engine)() as db:
        member = accounts.create_user(db, "member", "another horse battery staple", "member")
        member_id = member.id
        db.commit()
    engine.dispose()
    theirs = TestClient(client.app)
    log_in(theirs, {"username": "member", "password": "another horse battery staple"})
    cm, closes = _open(theirs)
    r = client.patch(f"/api/users/{member_id}", json={"active": False})
    assert r.status_code == 200, r.text
    _closed(client, closes)
    assert closes.reason == "account disabled"
    cm.__exit__(None, None, None)


def test_a_binary_frame_closes_with_1003_and_one_log_line(
        client: TestClient, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    with client.websocket_connect("/ws/live") as ws:
        assert ws.receive_json()["type"] == "status"
        ws.send_bytes(b"\x00\x01")
        message = ws.receive()
        assert message["type"] == "websocket.close" and message["code"] == 1003
    wait_for(lambda: client.get("/api/health").json()["clients"] == 0, 15,
             "health to count no console")
    errors = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(errors) == 1 and "binary frame" in errors[0].getMessage()
    assert errors[0].exc_info is None


def test_health_counts_open_consoles_only(client: TestClient) -> None:
    runtime = client.app.state.runtime  # type: ignore[attr-defined]
    # An in-process follower (the 3D view's pose updater) is not a console.
    follower = runtime.stream.connect(console=False)
    assert client.get("/api/health").json()["clients"] == 0
    with client.websocket_connect("/ws/live") as ws:
        ws.receive_json()
        assert client.get("/api/health").json()["clients"] == 1
    wait_for(lambda: client.get("/api/health").json()["clients"] == 0, 15,
             "the closed console to leave the count")
    runtime.stream.disconnect(follower)


def test_an_expired_login_is_noticed_without_a_request(client: TestClient) -> None:
    from datetime import UTC, datetime, timedelta

    from sqlalchemy import update

    from backend.api import socket_logins
    from backend.db.models import AuthToken

    socket_logins.RECHECK_S, before = 0.2, socket_logins.RECHECK_S
    try:
        cm, closes = _open(client)
        engine = make_engine(str(client.app.state.settings.database_url))  # type: ignore[attr-defined]
        with engine.begin() as conn:
            conn.execute(update(AuthToken).values(
                expires_at=datetime.now(UTC) - timedelta(seconds=1)))
        engine.dispose()
        _closed(client, closes)
        assert closes.reason == "login expired"
        cm.__exit__(None, None, None)
    finally:
        socket_logins.RECHECK_S = before
