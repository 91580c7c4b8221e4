"""The API fuzzed against its own OpenAPI schema (schemathesis): whatever a logged-in
caller sends, no server error, and every answer matches the documented status codes,
content types and response schemas."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi import FastAPI
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from schemathesis import GenerationMode
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.main import create_app
from backend.study import accounts
from tests.databases import fresh_database
from tests.login import create_experimenter, log_in


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
    schema (building the app has no side effects; only its lifespan touches anything).
    Invalid input is generated only where an operation takes any input."""
    app = create_app(Settings(_env_file=None, start_worker=False))  # type: ignore[call-arg]
    cases = []
    for path, item in app.openapi()["paths"].items():
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


# schemathesis' own pytest plugin (`schema.parametrize`) reads a node attribute pytest 9
# removed, so the cases are drawn with hypothesis directly from each operation.
@pytest.mark.parametrize(("method", "path", "mode"), [
    pytest.param(m, p, g, id=f"{m} {p} {'valid' if g == GenerationMode.POSITIVE else 'invalid'}")
    for m, p, g in _cases()])
def test_api_has_no_server_errors(method: str, path: str, mode: GenerationMode,
                                  api_schema: Any,
                                  fuzz_target: tuple[FastAPI, dict[str, str]]) -> None:
    operation = api_schema[path][method]
    headers = fuzz_target[1]

    @given(case=operation.as_strategy(generation_mode=mode))
    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def run(case: Any) -> None:
        case.call_and_validate(headers=headers, checks=CHECKS)

    run()
