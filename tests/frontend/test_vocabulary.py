"""The browser's vocabulary, as served: the same names as the Python definitions."""

from __future__ import annotations

import json
from typing import get_args

from fastapi.testclient import TestClient

from backend.schemas.evidence import SegmentLabel
from backend.schemas.live import STREAM_FIELDS, DatabaseHealth, DeviceHealth, WorkerHealth
from controller.controllers import registry
from controller.evaluation.lifts import CORRECT_ACTION
from controller.sim.scripts import SCRIPT_NAMES
from controller.tick_record import CATEGORY_NAMES, MODEL_NAMES, Action, Plausibility, TickRecord

PREFIX = "const VOCABULARY = "


def test_json_and_module_carry_the_python_definitions(client: TestClient) -> None:
    v = client.get("/api/vocabulary").json()
    assert v["tick_fields"] == list(TickRecord.field_names())
    assert v["stream_fields"] == list(STREAM_FIELDS)
    assert [m["name"] for m in v["models"]] == list(MODEL_NAMES)
    assert [m["correct_action"] for m in v["models"]] == [CORRECT_ACTION[m].name.lower()
                                                          for m in MODEL_NAMES]
    assert [c["name"] for c in v["categories"]] == list(CATEGORY_NAMES)
    assert [s["name"] for s in v["segment_labels"]] == list(get_args(SegmentLabel))
    assert [(a["value"], a["name"], a["lock_left"], a["lock_right"]) for a in v["actions"]] == [
        (int(a), a.name.lower(), *a.locks) for a in Action]
    assert [(p["bit"], p["name"]) for p in v["plausibility"]] == [
        (int(p), str(p.name).lower()) for p in Plausibility if p]
    assert sorted(c["name"] for c in v["controllers"]) == sorted(registry.names())
    assert {c["name"] for c in v["controllers"] if c["needs_models"]} == {
        n for n in registry.names() if (r := registry.lookup(n)) is not None and r.needs_models}
    assert {c["name"]: c["label"] for c in v["controllers"]}["eumc"] == "E-UMC"
    assert v["scripts"] == list(SCRIPT_NAMES)
    assert v["health"] == {"worker": list(WorkerHealth.model_fields),
                           "device": list(DeviceHealth.model_fields),
                           "database": list(DatabaseHealth.model_fields)}

    r = client.get("/static/vocabulary.js")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/javascript")
    line = next(x for x in r.text.splitlines() if x.startswith(PREFIX))
    assert json.loads(line[len(PREFIX):].rstrip(";")) == v
    assert "export default" in r.text


def test_the_module_is_a_static_asset_and_the_json_is_api(client: TestClient) -> None:
    """The module names, like every script, reach the login page; the JSON is API."""
    client.cookies.clear()
    assert client.get("/static/vocabulary.js").status_code == 200
    assert client.get("/api/vocabulary").status_code == 401
    assert client.get("/favicon.ico").headers["content-type"] == "image/svg+xml"


def test_a_registered_controller_reaches_the_browser(client: TestClient) -> None:
    """A researcher's fourth controller shows up in every page's lists without a page edit."""

    def build(spec: object) -> object:
        raise AssertionError("the vocabulary only names controllers")

    registry.register("trivial_vocab", needs_models=True, needs_calibration=True,
                      colour="#123456")(build)  # type: ignore[arg-type]
    try:
        v = client.get("/api/vocabulary").json()
        added = [c for c in v["controllers"] if c["name"] == "trivial_vocab"]
        assert added == [{"name": "trivial_vocab", "label": "trivial_vocab", "needs_models": True,
                          "needs_calibration": True, "estimates_intent": False,
                          "colour": "#123456", "in_plan": False, "plan_optional": False,
                          "idle": False, "baseline": False, "exoskeleton_worn": True}]
        assert v["controllers"][-1]["name"] == "none"
        assert "trivial_vocab" in client.get("/static/vocabulary.js").text
    finally:
        registry.unregister("trivial_vocab")
    assert "trivial_vocab" not in client.get("/static/vocabulary.js").text
