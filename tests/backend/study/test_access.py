"""Access: every operation in the OpenAPI schema refuses an anonymous caller, except
health, login and the participant forms; a participant token opens its own forms and
nothing else."""

from __future__ import annotations

import re
from typing import Any

import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.main import create_app

#: The only operations a caller without a login may use.
PUBLIC = {
    ("get", "/api/health"),
    ("post", "/api/auth/login"),
    ("post", "/api/auth/token"),
}
PARTICIPANT_PREFIX = "/api/participant-forms/"

SAMPLE_PATH_VALUES = {"key": "sus", "version": "1.0"}


def _operations(app: Any) -> list[tuple[str, str]]:
    ops = []
    for path, item in app.openapi()["paths"].items():
        for method in item:
            if method in {"get", "post", "put", "patch", "delete"}:
                ops.append((method, path))
    return ops


def _concrete(path: str, token: str = "x" * 43) -> str:
    def value(m: re.Match[str]) -> str:
        name = m.group(1)
        return token if name == "token" else SAMPLE_PATH_VALUES.get(name, "1")

    return re.sub(r"\{(\w+)\}", value, path)


def _seed(client: TestClient) -> tuple[str, str]:
    """Two participants, each with a link; returns both tokens."""
    client.post("/api/studies", json={"name": "access"})
    tokens = []
    for code in ("P01", "P02"):
        pid = client.post("/api/studies/1/participants", json={"code": code}).json()["id"]
        client.post(f"/api/participants/{pid}/conditions",
                    json={"label": "A", "controller": "umc"})
        r = client.post(f"/api/participants/{pid}/links",
                        json={"forms": [{"instrument_key": "sus", "condition_label": "A"}]})
        assert r.status_code == 201, r.text
        tokens.append(r.json()["token"])
    return tokens[0], tokens[1]


def test_the_schema_lists_the_study_routes(client: TestClient) -> None:
    ops = set(_operations(client.app))
    assert len(ops) >= 30
    for expected in [("post", "/api/studies"), ("get", "/api/audit"),
                     ("post", "/api/participants/{participant_id}/links"),
                     ("post", "/api/participant-forms/{token}/responses"),
                     ("post", "/api/worker/controller")]:
        assert expected in ops


def test_every_route_refuses_an_anonymous_caller(client: TestClient) -> None:
    _seed(client)
    anonymous = TestClient(client.app)
    checked = 0
    for method, path in _operations(client.app):
        if (method, path) in PUBLIC or path.startswith(PARTICIPANT_PREFIX):
            continue
        r = anonymous.request(method.upper(), _concrete(path), json={})
        assert r.status_code == 401, f"{method.upper()} {path} answered {r.status_code}"
        checked += 1
    assert checked >= 25


def test_a_participant_token_reaches_nothing_but_its_own_forms(client: TestClient) -> None:
    token_1, token_2 = _seed(client)
    outsider = TestClient(client.app)
    for method, path in _operations(client.app):
        if (method, path) in PUBLIC or path.startswith(PARTICIPANT_PREFIX):
            continue
        for how in ({"headers": {"Authorization": f"Bearer {token_1}"}},
                    {"cookies": {"exostudy_session": token_1}}):
            outsider.cookies.clear()
            for k, v in how.get("cookies", {}).items():
                outsider.cookies.set(k, v)
            r = outsider.request(method.upper(), _concrete(path), json={},
                                 headers=how.get("headers"))
            assert r.status_code == 401, f"{method.upper()} {path} with a participant token"
    outsider.cookies.clear()
    # Each token opens its own participant's forms; nothing in them names the other
    # participant, a controller, or a participant id.
    mine = outsider.get(f"/api/participant-forms/{token_1}")
    assert mine.status_code == 200
    assert "umc" not in mine.text.lower() and "P0" not in mine.text
    answers = {f"q{i}": 3 for i in range(1, 11)}
    outsider.post(f"/api/participant-forms/{token_1}/responses",
                  json={"form": 0, "answers": answers})
    responses_2 = client.get("/api/participants/2/responses").json()
    assert responses_2 == []
    assert [r["participant_id"] for r in client.get("/api/participants/1/responses").json()] == [1]
    # An unknown or guessed token opens nothing.
    assert outsider.get(f"/api/participant-forms/{'A' * 43}").status_code == 404
    assert outsider.get(f"/api/participant-forms/{token_2}").status_code == 200


@pytest.mark.parametrize("page", ["/live"])
def test_pages_need_a_login(settings: Settings, page: str) -> None:
    with TestClient(create_app(settings)) as anonymous:
        r = anonymous.get(page, follow_redirects=False)
    assert r.status_code == 303 and r.headers["location"].startswith("/login")


def test_the_schema_says_which_operations_need_a_login(client: TestClient) -> None:
    for path, item in client.app.openapi()["paths"].items():  # type: ignore[attr-defined]
        for method, op in item.items():
            public = (method, path) in PUBLIC or path.startswith(PARTICIPANT_PREFIX)
            assert bool(op.get("security")) is not public, f"{method.upper()} {path}"
            if not public:
                assert "401" in op["responses"], f"{method.upper()} {path} lacks its 401"
