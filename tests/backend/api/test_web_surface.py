"""The hardened web surface: CSRF (Origin and token), WebSocket Origin, security
headers, local /docs, the body-size limit and bad input answered with 4xx."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from starlette.websockets import WebSocketDisconnect

from backend.api.web_surface import CSRF_COOKIE
from tests.databases import AccountTemplates
from tests.login import bearer
from tests.module_client import logged_in_client

EVIL = "http://evil.example"


@pytest.fixture(scope="module")
def reader(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path],
           account_templates: AccountTemplates) -> Iterator[TestClient]:
    """One logged-in app for the tests here that only read (`tests/module_client.py`);
    the tests that write or change the client's headers get their own `client`."""
    with logged_in_client(tmp_path_factory.mktemp("web-surface"), default_sets,
                          account_templates) as c:
        yield c


def test_a_cookie_change_from_another_origin_or_without_the_token_is_refused(
        client: TestClient) -> None:
    token = client.headers["X-CSRF-Token"]
    for headers in ({"Origin": EVIL}, {"Origin": EVIL, "X-CSRF-Token": token},
                    {"X-CSRF-Token": ""}, {"Referer": EVIL + "/page", "Origin": ""}):
        r = client.post("/api/worker/stop", headers=headers)
        assert r.status_code == 403, (headers, r.text)
    r = client.post("/api/studies", json={"name": "x"}, headers={"Origin": EVIL})
    assert r.status_code == 403 and "Origin" in r.json()["detail"]
    assert client.get("/api/studies").json() == []  # nothing was created
    # Same origin and the token: allowed (the worker is not running here: 409, not 403).
    assert client.post("/api/worker/stop").status_code != 403
    assert client.post("/api/studies", json={"name": "x"}).status_code == 201
    # The token is the login's: the cookie of another login does not match it.
    assert client.cookies.get(CSRF_COOKIE) == token


def test_a_login_from_another_origin_is_refused_and_bearer_scripts_need_no_token(
        client: TestClient, experimenter: dict[str, str]) -> None:
    anon = TestClient(client.app)
    assert anon.post("/api/auth/login", json=experimenter,
                     headers={"Origin": EVIL}).status_code == 403
    r = anon.post("/api/auth/token", json=experimenter)
    h = {"Authorization": f"Bearer {r.json()['access_token']}", "Origin": EVIL}
    assert anon.post("/api/studies", json={"name": "by script"}, headers=h).status_code == 201


def test_a_websocket_from_another_origin_is_refused(client: TestClient) -> None:
    with pytest.raises(WebSocketDisconnect), \
            client.websocket_connect("/ws/live", headers={"Origin": EVIL}) as ws:
        ws.receive_text()
    with client.websocket_connect("/ws/live", headers={"Origin": "http://testserver"}) as ws:
        assert ws.receive_json()["type"] == "status"


@pytest.mark.parametrize("path", ["/login", "/api/health", "/static/style.css", "/docs",
                                  "/api/studies"])
def test_every_response_carries_the_security_headers(reader: TestClient, path: str) -> None:
    r = reader.get(path)
    assert r.status_code == 200
    csp = r.headers["content-security-policy"]
    assert "frame-ancestors 'none'" in csp and "script-src 'self'" in csp
    assert "unsafe-inline" not in csp.split("script-src", 1)[1].split(";", 1)[0]
    assert r.headers["x-frame-options"] == "DENY"
    assert r.headers["x-content-type-options"] == "nosniff"
    assert r.headers["referrer-policy"] == "same-origin"


def test_docs_load_only_local_assets(client: TestClient) -> None:
    page = client.get("/docs").text
    assert "http://" not in page and "https://" not in page and "cdn" not in page.lower()
    for asset in ("/docs-assets/swagger-ui-bundle.js", "/docs-assets/swagger-ui.css",
                  "/static/docs/init.js"):
        assert asset in page
        assert client.get(asset).status_code == 200


def test_a_huge_body_is_refused_with_413_before_it_is_read(client: TestClient) -> None:
    anon = TestClient(client.app)
    big = b'{"username": "x", "password": "' + b"a" * 2_000_000 + b'"}'
    r = anon.post("/api/auth/login", content=big, headers={"Content-Type": "application/json"})
    assert r.status_code == 413
    assert r.json()["detail"][0]["loc"] == ["body"]

    def chunks() -> Iterator[bytes]:  # no Content-Length: the limit counts the streamed bytes
        yield b'{"username": "x", "password": "'
        for _ in range(40):
            yield b"a" * 100_000
        yield b'"}'

    r = anon.post("/api/auth/login", content=chunks(),
                  headers={"Content-Type": "application/json"})
    assert r.status_code == 413


@pytest.mark.parametrize(("body", "field"), [
    (b'{"code": "P01", "mass_kg": NaN}', "mass_kg"),
    (b'{"code": "P01", "mass_kg": Infinity}', "mass_kg"),
    (b'{"code": "P01", "mass_kg": -Infinity}', "mass_kg"),
    (b'{"code": "P01", "age": 123456789012345678901234567890}', "age"),
    (b'{"code": "P\\u0000"}', "code"),
    (b'{"code": "P01", "notes": "a\\u0000b"}', "notes"),
    (b'{"code": "P01", "notes": "\\ud800"}', "notes"),
])
def test_bad_numbers_and_characters_get_a_422_naming_the_field(
        client: TestClient, body: bytes, field: str) -> None:
    assert client.post("/api/studies", json={"name": "s"}).status_code == 201
    r = client.post("/api/studies/1/participants", content=body,
                    headers={"Content-Type": "application/json"})
    assert r.status_code == 422, r.text
    assert field in {str(x) for e in r.json()["detail"] for x in e["loc"]}
    assert client.get("/api/studies/1/participants").json() == []


@pytest.mark.parametrize("path", ["/api/participants/123456789012345678901234567890",
                                  "/api/trials/99999999999999999999/segments",
                                  "/api/studies/-1", "/api/studies/1e3",
                                  # Beyond int()'s 4,300-digit limit (a ValueError, once a 500).
                                  "/api/studies/" + "9" * 4301,
                                  "/api/sessions/" + "9" * 4301 + "/xdf",
                                  "/api/participants/" + "9" * 4301,
                                  "/api/trials/" + "9" * 4301,
                                  "/api/trials/" + "0" * 5000 + "1"])
def test_ids_beyond_any_column_get_a_4xx(reader: TestClient, path: str) -> None:
    r = reader.get(path)
    assert 400 <= r.status_code < 500 and r.status_code != 403, (path, r.text)


def test_names_are_bounded(client: TestClient) -> None:
    r = client.post("/api/studies", json={"name": "x" * 201})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "name"]
    r = client.post("/api/studies", json={"name": "x" * 5_000_000})
    assert r.status_code == 413


# The values that turned 44 of 188 bad inputs into 500s: non-finite floats, integers
# beyond 64 bits, NUL, lone surrogates and very long strings. Hypothesis draws them (and
# their neighbours) into every field of every JSON body the API takes.
HOSTILE = st.one_of(
    st.sampled_from([float("nan"), float("inf"), float("-inf")]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=2**63 - 2, max_value=2**80) | st.integers(max_value=-(2**63)),
    st.text(st.characters(categories=["Cs"]), min_size=1, max_size=3),
    st.text(alphabet=st.sampled_from(["\x00", "a", "\ud800", "é"]), min_size=1),
    st.just("x" * 70_000),
)


#: Drawn requests per run; `EXOSTUDY_FUZZ_EXAMPLES=...` (as for schemathesis) digs deeper.
HOSTILE_EXAMPLES = 15 * int(os.environ.get("EXOSTUDY_FUZZ_EXAMPLES", "4"))


def _json_bodies(schema: dict[str, Any]) -> list[tuple[str, str, list[str]]]:
    """(method, path, property names) of every operation with a JSON object body."""
    out = []
    components = schema.get("components", {}).get("schemas", {})
    for path, item in schema["paths"].items():
        for method, op in item.items():
            body = op.get("requestBody", {}).get("content", {}).get("application/json")
            if not body:
                continue
            ref = body["schema"].get("$ref", "")
            props = components.get(ref.rsplit("/", 1)[-1], {}).get("properties", {})
            if props:
                out.append((method, path, sorted(props)))
    return out


def test_hostile_values_in_any_body_field_never_get_a_server_error(
        client: TestClient, experimenter: dict[str, str]) -> None:
    client.post("/api/studies", json={"name": "s"})
    client.post("/api/studies/1/participants", json={"code": "P01"})
    client.post("/api/participants/1/sessions", json={"kind": "evaluation",
                                                     "precompression_pct": 25})
    anon = TestClient(client.app)
    h = {**bearer(anon, experimenter), "Content-Type": "application/json"}
    ops = [op for op in _json_bodies(client.app.openapi())  # type: ignore[attr-defined]
           if op[1] not in ("/api/auth/password", "/api/users/{user_id}")]
    assert len(ops) >= 20

    @given(data=st.data())
    @settings(max_examples=HOSTILE_EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def run(data: st.DataObject) -> None:
        method, path, props = data.draw(st.sampled_from(ops))
        field = data.draw(st.sampled_from(props))
        value = data.draw(HOSTILE)
        raw = json.dumps({field: value}, allow_nan=True).encode("utf-8", "surrogatepass")
        url = re.sub(r"\{\w+\}", "1", path)
        r = anon.request(method.upper(), url, content=raw, headers=h)
        assert r.status_code < 500, (method, path, field, repr(value)[:80], r.text[:300])

    run()


def test_a_csv_field_over_the_csv_modules_limit_is_a_422(client: TestClient) -> None:
    assert client.post("/api/studies", json={"name": "s"}).status_code == 201
    csv_text = "motion,leg,n,theta_rad,tau_nm\nsquat,left," + "9" * 200_000 + ",0.1,2\n"
    r = client.post("/api/studies/1/utility-sets/import",
                    data={"name": "lab data", "precompression_pct": "25"},
                    files={"file": ("data.csv", csv_text.encode(), "text/csv")})
    assert r.status_code == 422, r.text
    assert "field larger" in r.json()["detail"][0]["msg"]
