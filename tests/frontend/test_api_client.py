"""The pages' API client: current with the routes, the only place a route is spelled,
and a renamed route is a lint error in the page that calls it."""

from __future__ import annotations

import copy
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
from fastapi import APIRouter, FastAPI

from backend.api.js_client import CLIENT_FILE, app_client_module, app_sockets, client_module
from backend.api.openapi import name_operations, operation_name
from backend.core.config import Settings
from backend.main import create_app

ROOT = Path(__file__).resolve().parents[2]
STATIC = ROOT / "frontend" / "static"
ESLINT = ROOT / "frontend" / "node_modules" / ".bin" / "eslint"
REGENERATE = ".venv/bin/python -m backend.api.js_client"


@pytest.fixture(scope="module")
def app(tmp_path_factory: pytest.TempPathFactory) -> FastAPI:
    db = tmp_path_factory.mktemp("client") / "app.db"
    return create_app(Settings(database_url=f"sqlite:///{db}", start_worker=False))


def test_the_committed_client_is_current(app: FastAPI) -> None:
    committed = (STATIC / CLIENT_FILE).read_text()
    assert committed == app_client_module(app), (
        f"frontend/static/{CLIENT_FILE} does not match the routes: run `{REGENERATE}`")


def test_no_page_spells_a_route() -> None:
    """Only the generated client names `/api/...` or `/ws/...` (comments included)."""
    files = [p for p in sorted(STATIC.glob("*.js")) if p.name != CLIENT_FILE]
    files += sorted(STATIC.glob("*.html")) + sorted((ROOT / "frontend" / "pages").glob("*.html"))
    assert len(files) > 20, files
    spelled = [f"{p.relative_to(ROOT)}:{n}: {line.strip()}"
               for p in files for n, line in enumerate(p.read_text().splitlines(), 1)
               if "/api/" in line or "/ws/" in line]
    assert spelled == []


@pytest.mark.parametrize(("function", "tag", "name"), [
    ("start_trial", "trials", "trials.start"),
    ("list_studies", "studies", "studies.list"),
    ("get_study", "studies", "studies.get"),
    ("list_trial_segments", "trials", "trials.listTrialSegments"),
    ("get_forms", "participant forms", "participantForms.get"),
    ("health", "health", "health.health"),
    ("study_results", "results", "results.study"),
    ("fit_models", "models", "models.fit"),
])
def test_operation_names(function: str, tag: str, name: str) -> None:
    assert operation_name(function, tag) == name


def test_two_routes_with_one_name_stop_the_app() -> None:
    router = APIRouter(tags=["trials"])

    @router.get("/api/trials")
    def list_trials() -> list[int]:
        return []

    @router.get("/api/other-trials")
    def list_trial() -> list[int]:
        return []

    app = FastAPI()
    app.include_router(router)
    with pytest.raises(RuntimeError, match=r"trials\.list.*/api/other-trials.*/api/trials"):
        name_operations(app, [router])


def test_every_operation_is_named_and_the_socket_found(app: FastAPI) -> None:
    schema = app.openapi()
    ids = [op["operationId"] for item in schema["paths"].values() for op in item.values()]
    assert len(ids) == len(set(ids)) > 100
    assert all(re.fullmatch(r"[a-z][A-Za-z]*\.[a-z][A-Za-z0-9]*", i) for i in ids), ids
    assert schema["paths"]["/api/trials/{trial_id}/start"]["post"]["operationId"] == "trials.start"
    assert app_sockets(app) == {"live": "/ws/live"}


def _lint_with(client: str, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    """ESLint over the pages, checking their calls against `client` instead."""
    node = shutil.which("node")
    if node is None or not ESLINT.is_file():
        pytest.fail("node and ESLint are needed: `make install`")
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / CLIENT_FILE).write_text(client)
    shutil.copy(STATIC / "api.js", tmp_path / "api.js")  # the client's one import
    env = {**os.environ, "EXOSTUDY_API_CLIENT": str(tmp_path / CLIENT_FILE)}
    return subprocess.run(
        [node, str(ESLINT), "--max-warnings", "0", "-c", "frontend/eslint.config.mjs",
         "frontend/static"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


def _rename(schema: dict[str, Any], old: str, new: str) -> dict[str, Any]:
    schema = copy.deepcopy(schema)
    found = [op for item in schema["paths"].values() for op in item.values()
             if op["operationId"] == old]
    assert len(found) == 1
    found[0]["operationId"] = new
    return schema


def test_a_renamed_route_fails_the_pages_lint(app: FastAPI, tmp_path: Path) -> None:
    """`start_trial` renamed `begin_trial` on the server: once the client is regenerated,
    every page still calling `api.trials.start` is an error, and nothing else is."""
    callers = {p.name: len(re.findall(r"\bapi\.trials\.start\b", p.read_text()))
               for p in STATIC.glob("*.js") if p.name != CLIENT_FILE}
    callers = {k: v for k, v in callers.items() if v}
    assert callers == {"session.js": 1}

    same = _lint_with(app_client_module(app), tmp_path / "same")  # the control
    assert same.returncode == 0, same.stdout[-3000:] + same.stderr[-3000:]

    renamed = client_module(_rename(app.openapi(), "trials.start", "trials.begin"),
                            app_sockets(app))
    run = _lint_with(renamed, tmp_path / "renamed")
    assert run.returncode == 1, run.stdout[-3000:] + run.stderr[-3000:]
    errors = [line for line in run.stdout.splitlines() if "error" in line and ":" in line]
    assert len(errors) == sum(callers.values()), run.stdout
    assert all("api.trials has no operation 'start'" in e for e in errors), run.stdout
    assert "session.js" in run.stdout


def test_a_removed_namespace_fails_the_pages_lint(app: FastAPI, tmp_path: Path) -> None:
    """A tag renamed (here `cohorts`): the import of its namespace fails."""
    schema = copy.deepcopy(app.openapi())
    for item in schema["paths"].values():
        for op in item.values():
            op["operationId"] = op["operationId"].replace("cohorts.", "virtualCohorts.")
    run = _lint_with(client_module(schema, app_sockets(app)), tmp_path)
    assert run.returncode == 1
    assert "api_client.js has no export 'cohorts'" in run.stdout
    assert "cohorts.js" in run.stdout


def test_a_moved_route_changes_only_the_client(app: FastAPI) -> None:
    """A path changed under the same name: the pages need no edit, the stale client
    fails the currency test above, and the new client asks the new path."""
    schema = copy.deepcopy(app.openapi())
    schema["paths"]["/api/trials/{trial_id}/begin"] = schema["paths"].pop(
        "/api/trials/{trial_id}/start")
    text = client_module(schema, app_sockets(app))
    assert text != (STATIC / CLIENT_FILE).read_text()
    assert '"trials.start", "POST", "/api/trials/{trial_id}/begin"' in text
    assert "/api/trials/{trial_id}/start" not in text


def test_a_path_parameter_the_path_lacks_is_refused(app: FastAPI) -> None:
    schema = copy.deepcopy(app.openapi())
    op = schema["paths"]["/api/trials/{trial_id}/start"]["post"]
    op["parameters"][0]["name"] = "id"
    with pytest.raises(ValueError, match=r"/api/trials/\{trial_id\}/start: path parameters"):
        client_module(schema, app_sockets(app))
