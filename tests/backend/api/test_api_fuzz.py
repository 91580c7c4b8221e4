"""The API fuzzed against its own OpenAPI schema (schemathesis): whatever a logged-in
caller sends, no server error, and every answer matches the documented status codes,
content types and response schemas. Then hostile JSON on every route: bodies nested
50,000 deep, NaN and infinities, integers beyond 64 bits, NUL, wrong types, in place of
the whole body or of one value of a valid one; never a 5xx, and what JSON or a database
cannot hold is refused at the door (422)."""

from __future__ import annotations

import copy
import json
import math
import os
import re
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
from schemathesis.checks import not_a_server_error
from schemathesis.python import asgi
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from backend.analysis import jobs
from backend.api.json_text import MAX_DEPTH
from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.main import create_app
from backend.study import accounts
from tests.databases import fresh_database
from tests.login import create_experimenter, log_in
from tests.openapi_document import documented


@pytest.fixture(scope="module")
def fuzz_target(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path]
                ) -> Iterator[tuple[FastAPI, dict[str, str]]]:
    """One app on one migrated database with a study, a participant with two blinded
    conditions and an open link, so fuzzed ids reach real rows; plus a bearer token."""
    with fresh_database(tmp_path_factory.mktemp("fuzz")) as url:
        yield from _fuzz_target(url, default_sets)


def _fuzz_target(url: str, default_sets: tuple[Path, Path]
                 ) -> Iterator[tuple[FastAPI, dict[str, str]]]:
    models, folder = default_sets
    creds = create_experimenter(url)
    app = create_app(Settings(  # type: ignore[call-arg]
        database_url=url, start_worker=False, device_spawn_simulator=False,
        models_path=models, utilities_dir=folder, _env_file=None))
    with TestClient(app) as client:
        log_in(client, creds)
        client.post("/api/studies", json={"name": "fuzz"})
        client.post("/api/studies/1/participants", json={"code": "P01", "age": 30})
        for label, ctrl in (("A", "umc"), ("B", "pec")):
            client.post("/api/participants/1/conditions",
                        json={"label": label, "controller": ctrl})
        client.post("/api/participants/1/sessions",
                    json={"kind": "evaluation", "precompression_pct": 25})
        client.post("/api/participants/1/links",
                    json={"forms": [{"instrument_key": "sus", "condition_label": "A"}],
                          "preference": True})
    engine = make_engine(url)
    with make_session_factory(engine)() as db:
        user = accounts.authenticate(db, creds["username"], creds["password"])
        assert user is not None
        token, _ = accounts.issue_token(db, user, "bearer")
        db.commit()
    engine.dispose()
    yield app, {"Authorization": f"Bearer {token}"}


def _cases() -> list[tuple[str, str, GenerationMode]]:
    """(method, path, mode) for every documented operation, read from the app's own
    schema (`tests/openapi_document.py`, built once per test process).
    Invalid input is generated only where an operation takes any input."""
    cases = []
    for path, item in documented()["paths"].items():
        for method, op in item.items():
            if (method.upper(), path) in EXCLUDED:
                continue
            cases.append((method.upper(), path, GenerationMode.POSITIVE))
            if op.get("parameters") or op.get("requestBody"):
                cases.append((method.upper(), path, GenerationMode.NEGATIVE))
    return cases


# Excluded: logout would revoke the fuzzer's own token, and restarting the worker would
# spawn a real control process (both are tested directly elsewhere).
# Revoking all logins, or an admin's change to the fuzzer's own account, would end its
# token too (tests/backend/study/test_data_protection.py covers them).
# Starting a virtual cohort runs up to 1,000 simulated participants on the job thread
# (tests/backend/api/test_cohorts_api.py covers it, and its 4xx answers).
EXCLUDED = {("POST", "/api/auth/logout"), ("POST", "/api/worker/restart"),
            ("POST", "/api/auth/revoke-all"), ("PATCH", "/api/users/{user_id}"),
            ("POST", "/api/cohorts")}

#: Examples per operation and mode: small enough for the suite (< 60 s on two shared
#: cores); `EXOSTUDY_FUZZ_EXAMPLES=200 pytest tests/backend/api/test_api_fuzz.py` digs deeper.
EXAMPLES = int(os.environ.get("EXOSTUDY_FUZZ_EXAMPLES", "4"))

CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance,
          response_schema_conformance]


@pytest.fixture(scope="module")
def api_schema(fuzz_target: tuple[FastAPI, dict[str, str]]) -> Any:
    return schemathesis.openapi.from_asgi("/openapi.json", fuzz_target[0])


@pytest.fixture(scope="module")
def raw_client(fuzz_target: tuple[FastAPI, dict[str, str]]) -> Iterator[TestClient]:
    """The app started once for the module (its lifespan: migrations checked, worker
    runtime and job runner up), for every test here."""
    with TestClient(fuzz_target[0]) as c:
        yield c


@pytest.fixture(scope="module")
def fuzz_session(raw_client: TestClient, fuzz_target: tuple[FastAPI, dict[str, str]]
                 ) -> asgi.ASGIClient:
    """schemathesis' in-process client for the app `raw_client` has started. Left
    unentered on purpose: an entered one (what `call_and_validate` makes without a
    session) starts the app's lifespan, and schemathesis' pytest plugin ends it after
    every test, so each of the 300 operations paid a start and a stop: most of the
    module's time (alone on a shared 2-core machine, CPU 119 s before, 45 to 82 s
    after)."""
    app: Any = fuzz_target[0]  # an ASGI app; schemathesis types the scope as a dict
    return asgi.get_client(app)


@pytest.fixture(autouse=True)
def jobs_end_with_their_test(request: pytest.FixtureRequest) -> Iterator[None]:
    """Background work a test starts ends with it, as it did when each test started and
    stopped the app: a drawn `POST /api/replication` queues a report that takes minutes
    of CPU. The app's job runner is shut down (what it ran or queued ends `cancelled`,
    a report's child process is stopped) and replaced by a fresh one, as a restart
    would."""
    yield
    if "raw_client" not in request.fixturenames:
        return
    state = request.getfixturevalue("raw_client").app.state
    state.jobs.shutdown()
    state.jobs = jobs.JobRunner(state.sessions)


# schemathesis' own pytest plugin (`schema.parametrize`) reads a node attribute pytest 9
# removed, so the cases are drawn with hypothesis directly from each operation.
@pytest.mark.parametrize(("method", "path", "mode"), [
    pytest.param(m, p, g, id=f"{m} {p} {'valid' if g == GenerationMode.POSITIVE else 'invalid'}")
    for m, p, g in _cases()])
def test_api_has_no_server_errors(method: str, path: str, mode: GenerationMode,
                                  api_schema: Any, fuzz_session: asgi.ASGIClient,
                                  fuzz_target: tuple[FastAPI, dict[str, str]]) -> None:
    operation = api_schema[path][method]
    headers = fuzz_target[1]

    @given(case=operation.as_strategy(generation_mode=mode))
    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def run(case: Any) -> None:
        fuzz_session.cookies.clear()  # each call as from a new client, bearer token only
        case.call_and_validate(session=fuzz_session, headers=headers, checks=CHECKS)

    run()


# --- Hostile JSON ------------------------------------------------------------------------

#: Literals JSON does not have, or numbers no database column holds: refused at the door.
NOT_JSON_NUMBERS = (b"NaN", b"Infinity", b"-Infinity", b"1e999", b"-1e400",
                    b"9" * 25, b"-9223372036854775809")
#: Values of the wrong type or at the edges; the route answers them (never a 5xx).
EDGE_VALUES = (b"null", b"true", b"0", b"-1", b"1e308", b"5e-324", b"9223372036854775807",
               b"-9223372036854775808", b'""', b'"x"', b"[]", b"{}", b"[null]",
               b'{"": null}', b'"' + b"x" * 5000 + b'"', b'"\\u0000"', b'"\\ud800"')


def nested(depth: int, leaf: bytes = b"0", kind: str = "[") -> bytes:
    """`leaf` inside `depth` arrays (or objects, each with the key "a")."""
    if kind == "[":
        return b"[" * depth + leaf + b"]" * depth
    return b'{"a":' * depth + leaf + b"}" * depth


#: The issue's body: 50,000 arrays around a NUL, which once escaped as a RecursionError.
DEEP_NUL = nested(50_000, b'"\\u0000"')

hostile_values = st.one_of(
    st.sampled_from(NOT_JSON_NUMBERS + EDGE_VALUES),
    st.builds(nested, st.integers(1, 3 * MAX_DEPTH), st.sampled_from(NOT_JSON_NUMBERS
                                                                      + EDGE_VALUES[:4]),
              st.sampled_from(["[", "{"])),
    st.integers(-(2**80), 2**80).map(lambda n: str(n).encode()),
    st.floats(allow_nan=True, allow_infinity=True).map(lambda f: json.dumps(f).encode()),
    st.text(max_size=20).map(lambda t: json.dumps(t).encode()),
)


def refused_at_door(text: bytes) -> bool:
    """Whether the value alone makes any body a 422 before a route runs: nested too
    deep, or a number JSON or the databases do not have."""
    if max(text.count(b"["), text.count(b"{")) > MAX_DEPTH:
        return True
    core = text.replace(b'{"a":', b"").strip(b"[]}")
    if core in (b"NaN", b"Infinity", b"-Infinity"):
        return True
    if re.fullmatch(rb"-?[0-9]+", core):
        return not -(2**63) <= int(core) < 2**63
    if re.fullmatch(rb"-?[0-9.]+(?:[eE][+-]?[0-9]+)?", core):
        return math.isinf(float(core))
    return False


_MARK = "\u0001hostile\u0001"


def _places(doc: Any, path: tuple[str | int, ...] = ()) -> Iterator[tuple[str | int, ...]]:
    """Every value's place in a document (containers and leaves), the root first."""
    yield path
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _places(v, (*path, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _places(v, (*path, i))


def with_value(body: Any, where: tuple[str | int, ...], text: bytes) -> bytes:
    """The JSON text of `body` with the raw `text` at `where` (the whole body for ())."""
    if not where:
        return text
    doc = copy.deepcopy(body)
    here = doc
    for key in where[:-1]:
        here = here[key]
    here[where[-1]] = _MARK
    return json.dumps(doc).encode().replace(json.dumps(_MARK).encode(), text)


def _json_body(case: Any) -> Any:
    """The drawn body if it is JSON (None for no body, a form or a file)."""
    body = getattr(case, "body", None)
    try:
        json.dumps(body)
    except (TypeError, ValueError):
        return None
    return body if isinstance(body, dict | list) else None


def _operations() -> list[tuple[str, str, bool]]:
    """(method, path, takes JSON) of every documented operation."""
    return [(m.upper(), p, "application/json" in op.get("requestBody", {}).get("content", {}))
            for p, item in documented()["paths"].items() for m, op in item.items()]


OPERATIONS = _operations()


def test_every_route_refuses_the_deep_nul_body_and_non_numbers_without_a_5xx(
        raw_client: TestClient, fuzz_target: tuple[FastAPI, dict[str, str]]) -> None:
    """The whole body replaced, on every route (each path parameter 1), logged in; the
    excluded routes get only what the door refuses, so that none of them runs."""
    for method, path, _ in OPERATIONS:
        url = re.sub(r"\{[^}]+\}", "1", path)
        bodies = [DEEP_NUL, nested(MAX_DEPTH + 1, kind="{"), *NOT_JSON_NUMBERS[:4],
                  b'{"x": NaN}']
        if (method, path) not in EXCLUDED:
            bodies += [b"[]", b'"x"', b"null", b"{"]
        for body in bodies:
            r = raw_client.request(method, url, content=body, headers={
                **fuzz_target[1], "content-type": "application/json"})
            assert r.status_code < 500, (method, url, body[:40], r.text[:300])
            if body not in (b"[]", b'"x"', b"null", b"{"):
                assert r.status_code == 422, (method, url, body[:40], r.text[:300])


#: Examples per JSON operation (each sends `SENDS` bodies); `EXOSTUDY_FUZZ_EXAMPLES`
#: digs deeper.
HOSTILE_EXAMPLES = max(2, EXAMPLES // 2)
SENDS = 4


@pytest.mark.parametrize(("method", "path"), [
    pytest.param(m, p, id=f"{m} {p}") for m, p, takes_json in OPERATIONS
    if takes_json and (m, p) not in EXCLUDED])
def test_hostile_values_in_a_valid_body_never_answer_5xx(
        method: str, path: str, api_schema: Any, raw_client: TestClient,
        fuzz_target: tuple[FastAPI, dict[str, str]]) -> None:
    operation = api_schema[path][method]
    headers = {**fuzz_target[1], "content-type": "application/json"}

    @given(case=operation.as_strategy(generation_mode=GenerationMode.POSITIVE),
           data=st.data())
    @settings(max_examples=HOSTILE_EXAMPLES, deadline=None, derandomize=True,
              database=None, suppress_health_check=list(HealthCheck))
    def run(case: Any, data: st.DataObject) -> None:
        body = _json_body(case)
        places = list(_places(body))[:40] if body is not None else [()]
        for _ in range(SENDS):
            where = data.draw(st.sampled_from(places), label="where")
            text = data.draw(hostile_values, label="value")
            sent = with_value(body, where, text)
            r = raw_client.request(method, case.formatted_path, content=sent,
                                   headers=headers, params=case.query)
            assert r.status_code < 500, (where, text[:60], r.status_code, r.text[:300])
            if refused_at_door(text):
                assert r.status_code == 422, (where, text[:60], r.text[:300])

    run()
