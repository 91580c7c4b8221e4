"""The console's personalisation: the plan form plans a demonstration block and the
personal-models condition, shown per trial, and the study's model-sets page lists a
personal set with its provenance and a prior set with its values."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import ModelSetRecord, UtilitySetRecord
from tests.browser.login_page import log_in_through
from tests.live_server import running_server


@pytest.fixture
def server(settings: Settings) -> Iterator[str]:
    with running_server(settings) as url:
        yield url


def _ok(r: httpx.Response) -> Any:
    assert r.is_success, r.text
    return r.json()


def test_plan_personal_conditions_and_list_the_sets(server: str, page: Any,
                                                    settings: Settings,
                                                    experimenter: dict[str, str]) -> None:
    api = httpx.Client(base_url=server, timeout=30)
    api.headers["Authorization"] = "Bearer " + api.post(
        "/api/auth/token", json=experimenter).json()["access_token"]
    study = _ok(api.post("/api/studies", json={"name": "personal console"}))["id"]
    pid = _ok(api.post(f"/api/studies/{study}/participants", json={"code": "P01"}))["id"]
    session = _ok(api.post(f"/api/participants/{pid}/sessions",
                           json={"kind": "evaluation", "precompression_pct": 25}))["id"]
    engine = make_engine(settings.database_url)
    with make_session_factory(engine)() as db:
        doc = json.loads(Path(settings.models_path).read_text())
        pop = ModelSetRecord(study_id=study, name="population", status="ready", document=doc)
        us = UtilitySetRecord(
            study_id=study, name="defaults", precompression_pct=25, human_source="sim",
            status="ready",
            document=json.loads(next(Path(settings.utilities_dir).glob("*.json")).read_text()))
        db.add_all([pop, us])
        db.flush()
        db.add(ModelSetRecord(study_id=study, name="P01 MAP", status="ready", document=doc,
                              kind="personal", method="map", participant_id=pid,
                              base_model_set_id=pop.id,
                              params={"counts": {"squat": 5, "stoop_left": 4,
                                                 "stoop_right": 5}}))
        db.commit()
    engine.dispose()
    _ok(api.post(f"/api/participants/{pid}/prior-sets",
                 json={"name": "equal", "method": "equal", "utility_set_id": us.id}))

    log_in_through(page, server, f"/console/sessions/{session}", experimenter)
    page.wait_for_selector("#plan-personal-set option:nth-child(2)", state="attached")
    for task in ("stoop-sequence", "walking", "stairs"):
        page.uncheck(f"input[name=task][value={task}]")
    page.uncheck("#plan-eumc")
    page.check("input[name=plan-condition][value=personal]")
    page.check("#plan-demos")
    page.fill("#demo-squat", "4")
    page.click("#plan-run")
    page.wait_for_selector("#trials tbody tr")
    rows = page.eval_on_selector_all(
        "#trials tbody tr", "rows => rows.map(r => [r.dataset.controller, r.cells[1].innerText])")
    assert rows[0][0] == "none" and "demonstration block" in rows[0][1]
    assert sum("personal models" in text for _, text in rows) == 1
    trials = _ok(api.get(f"/api/sessions/{session}/trials"))
    assert trials[0]["demonstrations"] == {"squat": 4, "stoop_left": 5, "stoop_right": 5}
    assert sorted(t["condition"] for t in trials[1:]) == ["pec", "umc", "umc+personal"]

    page.goto(f"{server}/console/studies/{study}/model-sets")
    page.wait_for_selector("#model-sets tr[data-kind=personal]")
    personal = page.inner_text("#model-sets tr[data-kind=personal]")
    assert "P01" in personal and "map" in personal and "stoop_left 4" in personal
    assert f"#{pop.id} population" in personal
    page.wait_for_selector("#prior-sets tr[data-prior-set]")
    assert "0.250, 0.250, 0.250, 0.250" in page.inner_text("#prior-sets tr[data-prior-set]")
