"""Text no database can store (a lone surrogate, NUL) is a 422 naming the field, on
every route that takes JSON, never a 500 (a trial plan's task names gave one).

Schemathesis draws one valid body per operation from the app's own OpenAPI schema; each
string in it (up to `PER_OPERATION`) is then replaced in turn by a lone surrogate or
NUL, and the answer must be a 422 whose `loc` is that string's place in the body."""

from __future__ import annotations

import copy
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi import FastAPI
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from schemathesis import GenerationMode

from backend.api import json_text
from tests.backend.api.test_api_fuzz import EXCLUDED, _fuzz_target
from tests.databases import fresh_database
from tests.openapi_document import documented

#: Strings replaced per operation (the first ones of the drawn body).
PER_OPERATION = 6
BAD = ("\ud800", "\udfff", "a\x00b")


def _json_operations() -> list[tuple[str, str]]:
    """(method, path) of every operation that takes a JSON body."""
    out = []
    for path, item in documented()["paths"].items():
        for method, op in item.items():
            body = op.get("requestBody", {}).get("content", {})
            if "application/json" in body and (method.upper(), path) not in EXCLUDED:
                out.append((method.upper(), path))
    return out


OPERATIONS = _json_operations()


@pytest.fixture(scope="module")
def target(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path]
           ) -> Iterator[tuple[FastAPI, dict[str, str]]]:
    with fresh_database(tmp_path_factory.mktemp("storable")) as url:
        yield from _fuzz_target(url, default_sets)


def _strings(doc: Any, path: tuple[str | int, ...] = ()) -> Iterator[tuple[str | int, ...]]:
    if isinstance(doc, str):
        yield path
    elif isinstance(doc, dict):
        for k, v in doc.items():
            yield from _strings(v, (*path, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _strings(v, (*path, i))


def _set(doc: Any, path: tuple[str | int, ...], value: str) -> Any:
    out = copy.deepcopy(doc)
    here = out
    for key in path[:-1]:
        here = here[key]
    here[path[-1]] = value
    return out


def test_a_trial_plan_with_a_lone_surrogate_is_a_422(client: TestClient) -> None:
    assert client.post("/api/studies", json={"name": "s"}).status_code == 201
    assert client.post("/api/studies/1/participants", json={"code": "P01"}).status_code == 201
    assert client.post("/api/participants/1/sessions", json={
        "kind": "evaluation", "precompression_pct": 25}).status_code == 201
    r = client.post("/api/sessions/1/trials/plan", content=b'{"tasks": ["\\ud800"]}',
                    headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"] == ["body", "tasks", 0]
    assert client.get("/api/sessions/1/trials").json() == []  # nothing stored
    # A paired surrogate is an ordinary character (an emoji) and passes.
    r = client.post("/api/sessions/1/trials/plan", content=b'{"tasks": ["\\ud83d\\ude00"]}',
                    headers={"content-type": "application/json"})
    assert r.status_code < 500, r.text


@pytest.fixture(scope="module")
def api_schema(target: tuple[FastAPI, dict[str, str]]) -> Any:
    return schemathesis.openapi.from_asgi("/openapi.json", target[0])


@pytest.fixture(scope="module")
def raw_client(target: tuple[FastAPI, dict[str, str]]) -> Iterator[TestClient]:
    with TestClient(target[0]) as c:
        yield c


@pytest.mark.parametrize(("method", "path"), OPERATIONS, ids=[f"{m} {p}" for m, p in OPERATIONS])
def test_every_json_string_refuses_unstorable_text(
        method: str, path: str, api_schema: Any, raw_client: TestClient,
        target: tuple[FastAPI, dict[str, str]]) -> None:
    operation = api_schema[path][method]
    headers = {**target[1], "content-type": "application/json"}

    @given(case=operation.as_strategy(generation_mode=GenerationMode.POSITIVE))
    @settings(max_examples=1, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def run(case: Any) -> None:
        body = case.body
        url = case.formatted_path
        for i, where in enumerate(list(_strings(body))[:PER_OPERATION]):
            # json.dumps escapes the bad characters (\ud800, \u0000) as a client would.
            sent = json.dumps(_set(body, where, BAD[i % len(BAD)]))
            r = raw_client.request(method, url, content=sent, headers=headers,
                                   params=case.query)
            assert r.status_code == 422, (where, r.status_code, r.text[:300])
            assert ["body", *where] in [d["loc"] for d in r.json()["detail"]], r.text[:300]

    run()


JSON = {"content-type": "application/json"}


def test_a_body_nested_50000_deep_around_nul_is_a_422_before_login(client: TestClient
                                                                    ) -> None:
    """The parser's recursion once escaped the door as a 500 with a long traceback."""
    anonymous = TestClient(client.app)
    body = b"[" * 50_000 + b'"\\u0000"' + b"]" * 50_000
    r = anonymous.post("/api/auth/login", content=body, headers=JSON)
    assert r.status_code == 422, r.text[:300]
    assert r.json()["detail"] == [{
        "loc": ["body"], "type": "too_deep",
        "msg": "arrays and objects nested 50000 deep; at most 32 levels are accepted"}]
    # Exactly the limit passes the door (the route then refuses the shape).
    r = anonymous.post("/api/auth/login", content=b"[" * 32 + b"]" * 32, headers=JSON)
    assert r.status_code == 422 and r.json()["detail"][0]["type"] != "too_deep"


@pytest.mark.parametrize(("literal", "problem"), [
    ("NaN", "NaN is not a JSON number; numbers must be finite"),
    ("-Infinity", "-Infinity is not a JSON number; numbers must be finite"),
    ("1e999", "1e999 is beyond the largest float; numbers must be finite"),
    ("18446744073709551616", "18446744073709551616 is an integer beyond 64 bits")])
def test_numbers_json_or_the_database_cannot_hold_are_refused_where_they_are(
        client: TestClient, literal: str, problem: str) -> None:
    assert client.post("/api/studies", json={"name": "s"}).status_code == 201
    body = f'{{"code": "P01", "age": 30, "mass_kg": {literal}}}'.encode()
    r = client.post("/api/studies/1/participants", content=body, headers=JSON)
    assert r.status_code == 422, r.text
    assert r.json()["detail"] == [{"loc": ["body", "mass_kg"], "msg": problem,
                                   "type": "value_error"}]
    assert client.get("/api/studies/1/participants").json() == []  # nothing stored
    # Inside a string they are only text.
    r = client.post("/api/studies/1/participants", headers=JSON,
                    content=f'{{"code": "P01", "notes": "{literal} [[[["}}'.encode())
    assert r.status_code == 201, r.text


json_documents = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**63), 2**63 - 1)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(alphabet=st.sampled_from('[]{}"\\ax\u00e9\u2028'), max_size=8),
    lambda inner: st.lists(inner, max_size=3)
    | st.dictionaries(st.text(alphabet=st.sampled_from('[]{}"\\k'), max_size=4), inner,
                      max_size=3),
    max_leaves=30)


def _depth(doc: Any) -> int:
    if isinstance(doc, list):
        return 1 + max(map(_depth, doc), default=0)
    if isinstance(doc, dict):
        return 1 + max(map(_depth, doc.values()), default=0)
    return 0


@given(json_documents, st.booleans())
@settings(max_examples=300, deadline=None)
def test_the_door_measures_nesting_as_the_parser_would(doc: Any, ascii_only: bool) -> None:
    """Brackets and quotes inside strings (escaped or not) never count; the depth from
    the bytes is the depth of the parsed document."""
    text = json.dumps(doc, ensure_ascii=ascii_only).encode()
    assert json_text.nesting_depth(json_text._STRING.sub(b"", text)) == _depth(doc)
    if _depth(doc) <= json_text.MAX_DEPTH:
        assert json_text.problems(text) == []


NON_UTF8 = ["utf-16-le", "utf-16-be", "utf-16", "utf-32", "utf-32-le", "utf-32-be"]


@pytest.mark.parametrize(("encoding", "literal"), zip(NON_UTF8, ["NaN", "Infinity", "1e999"] * 2,
                                                       strict=True))
def test_a_body_in_utf16_or_utf32_is_refused_before_the_parser_reads_it(
        client: TestClient, encoding: str, literal: str) -> None:
    """Python's parser reads UTF-16/32 bytes too; the door once read them as UTF-8 and let
    `Infinity` through to be stored. Only UTF-8 is accepted."""
    assert client.post("/api/studies", json={"name": "s"}).status_code == 201
    body = f'{{"code": "P01", "mass_kg": {literal}}}'.encode(encoding)
    r = client.post("/api/studies/1/participants", content=body, headers=JSON)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert detail[0]["loc"] == ["body"] and detail[0]["type"] == "not_utf8"
    assert "must be UTF-8" in detail[0]["msg"]
    assert client.get("/api/studies/1/participants").json() == []  # nothing stored
    url = "/api/studies/1/emg-settings"
    before = client.get(url).json()
    text = f'{{"processing": {{"lowpass_hz": {literal}, "envelope_hz": {literal}}}}}'
    r = client.put(url, content=text.encode(encoding), headers=JSON)
    assert r.status_code == 422 and r.json()["detail"][0]["type"] == "not_utf8", r.text
    assert client.get(url).json() == before


@pytest.mark.parametrize("body", [
    b'\xef\xbb\xbf{"code": "P01"}',  # a UTF-8 byte-order mark (RFC 8259: must not be sent)
    b'{"code": "P\xed\xa0\x80"}',  # an encoded surrogate half: not UTF-8
    b'{"code": "P\xff01"}',  # not UTF-8 at all
    b'\x00{\x00"code": "P01"}',  # NUL bytes: the parser would guess UTF-16
    b'{"code": "P01"}\x00'])
def test_what_is_not_plain_utf8_is_refused_and_plain_utf8_passes(
        client: TestClient, body: bytes) -> None:
    assert client.post("/api/studies", json={"name": "s"}).status_code == 201
    r = client.post("/api/studies/1/participants", content=body, headers=JSON)
    assert r.status_code == 422 and r.json()["detail"][0]["type"] == "not_utf8", r.text
    assert client.get("/api/studies/1/participants").json() == []
    r = client.post("/api/studies/1/participants", headers=JSON,
                    content='{"code": "P01", "notes": "é ü 😀"}'.encode())
    assert r.status_code == 201, r.text


@given(st.binary(max_size=64))
@settings(max_examples=300, deadline=None)
def test_what_passes_the_encoding_check_the_parser_reads_as_utf8(body: bytes) -> None:
    """The door and the parser cannot disagree about the text: json.loads on any body the
    check lets through gives what json.loads on its UTF-8 decoding gives."""
    if json_text.encoding_problem(body) is not None:
        return
    text = body.decode("utf-8")
    try:
        from_bytes: Any = json.loads(body)
    except ValueError as exc:
        from_bytes = type(exc)
    try:
        from_text: Any = json.loads(text)
    except ValueError as exc:
        from_text = type(exc)
    assert from_bytes == from_text or (from_bytes != from_bytes and from_text != from_text)
