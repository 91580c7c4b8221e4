"""The worked example of docs/adding-a-controller.md takes part in everything a built-in
controller does, by what it declares in its registration alone: a study's plan (after
the paper's controllers), the refusal to start without a calibration, the replay and the
virtual cohort (which calibrate it from the recording's start), the results tables (it
estimates intent), the vocabulary the pages read, and a whole virtual study on a real
worker."""

from __future__ import annotations

import csv
import importlib
import io
import math
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from fastapi.testclient import TestClient

from backend.schemas.vocabulary import vocabulary
from backend.study.counterbalance import blinded_labels, controller_order
from backend.worker.messages import CalibrationResult
from controller.controllers import registry
from controller.evaluation.cohort import CohortConfig, cohort_controllers, simulate_cohort
from controller.evaluation.rendering import controller_colour, controller_marker
from controller.evaluation.study import controller_label, table_controllers

MODULE = "tests.controller.controllers.constant_controller"


@pytest.fixture
def constant(monkeypatch: pytest.MonkeyPatch) -> Iterator[ModuleType]:
    """The example registered for one test (a worker process learns of it from the
    environment), then removed again: other tests check the list of controllers."""
    monkeypatch.setenv(registry.ENV_MODULES, MODULE)
    mod = importlib.import_module(MODULE)  # importing it registers it
    if registry.lookup("constant") is None:  # removed after an earlier test
        importlib.reload(mod)
    yield mod
    registry.unregister("constant")


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def test_its_declarations_reach_every_place_that_decides(constant: ModuleType) -> None:
    reg = registry.get("constant")
    assert (reg.needs_calibration, reg.estimates_intent, reg.needs_models) == (True, True,
                                                                               False)
    assert registry.needs_calibration("constant") and not registry.needs_calibration("umc")
    assert registry.estimates_intent("constant") is True
    assert registry.estimates_intent("pec") is False and registry.estimates_intent("x") is None
    # The plan: it follows the counterbalanced pair, after the optional E-UMC.
    assert controller_order(0) == ["umc", "pec", "eumc", "constant"]
    assert controller_order(1, include_optional=False) == ["pec", "umc", "constant"]
    assert blinded_labels(controller_order(0))["constant"] == "D"
    assert cohort_controllers() == ("umc", "eumc", "pec", "constant")
    assert table_controllers() == ("pec", "umc", "eumc", "constant")
    assert table_controllers(intent_only=True) == ("umc", "eumc", "constant")
    # Labels, colours and markers in figures and on the pages.
    assert controller_label("constant") == "Constant"
    assert (controller_colour("constant"), controller_marker("constant")) == ("#2ca02c", "D")
    entry = next(c for c in vocabulary().controllers if c.name == "constant")
    assert (entry.label, entry.colour, entry.needs_calibration, entry.estimates_intent,
            entry.in_plan, entry.plan_optional, entry.idle) == (
        "Constant", "#2ca02c", True, True, True, False, False)
    assert [c.name for c in vocabulary().controllers][-1] == registry.idle() == "none"


def test_it_takes_part_in_a_virtual_cohort_calibrated(constant: ModuleType) -> None:
    cohort = simulate_cohort(CohortConfig(participants=2, seed=5,
                                          controllers=("constant", "pec")))
    assert all(p.calibration_attempts >= 1 for p in cohort.participants)
    # It estimates intent: its lifts are judged (never recognised: "other" leads at 0.5).
    assert list(cohort.values("constant", "recognised_pct")) == [0.0, 0.0]
    assert all(math.isnan(v) for v in cohort.values("pec", "recognised_pct"))
    assert list(cohort.values("constant", "fp_total")) == [0.0, 0.0]  # it never locks
    with pytest.raises(ValueError, match="controllers: choose from"):
        CohortConfig(participants=2, controllers=("mystery",))


def test_a_study_plans_it_and_refuses_to_start_it_uncalibrated(
    constant: ModuleType, client: TestClient
) -> None:
    study = _ok(client.post("/api/studies", json={"name": "Worked example"}), 201)
    p = _ok(client.post(f"/api/studies/{study['id']}/participants",
                        json={"code": "P01", "age": 30, "sex": "female", "height_m": 1.7,
                              "mass_kg": 65, "consent_date": "2026-11-20"}), 201)
    sess = _ok(client.post(f"/api/participants/{p['id']}/sessions",
                           json={"kind": "evaluation", "precompression_pct": 25}), 201)
    plan = _ok(client.post(f"/api/sessions/{sess['id']}/trials/plan",
                           json={"tasks": ["walking"], "include_eumc": False}), 201)
    assert [t["controller"] for t in plan] == ["umc", "pec", "constant"]
    trial = plan[-1]
    r = client.post(f"/api/trials/{trial['id']}/start", json={})
    assert r.status_code == 409 and "Constant needs a calibration" in r.text
    # With a calibration the runtime puts the offsets in its specification.
    runtime = client.app.state.runtime  # type: ignore[attr-defined]
    runtime.calibration = CalibrationResult(1, True, "calibrated", 0.05, -0.03)
    runtime.calibration_seed = seed = runtime.settings.device_seed  # made on this wearer
    spec = runtime.controller_spec("constant")
    assert spec.settings.calibration == (0.05, -0.03)
    assert runtime.controller_spec("pec").settings.calibration is None
    # Not on another virtual participant, whom it was not made on.
    other = runtime.controller_spec("constant", wearer_seed=seed + 1)
    assert other.settings.calibration is None


@pytest.mark.slow
def test_it_runs_in_a_virtual_study_on_a_real_worker(constant: ModuleType,
                                                    tmp_path: Path) -> None:
    from backend.analysis.virtual_study import DEFAULT_SPEED, VirtualStudyConfig, run

    out = tmp_path / "vs"
    cfg = VirtualStudyConfig(out=out, participants=1, data_participants=2, eumc=0, seed=7,
                             speed=DEFAULT_SPEED, rates=("paper-rates",), margin_s=4.0,
                             model_evaluation=False)
    report = run(cfg, log=lambda _m: None)
    assert [t.controller for t in report.trials] == ["umc", "pec", "constant"]
    mine = report.trials[-1]
    assert mine.calibration_attempts >= 1 and mine.gaps == 0 and mine.ticks > 1000
    folder = out / "paper-rates"
    perf = list(csv.DictReader(io.StringIO((folder / "performance.csv").read_text())))
    assert {r["controller"] for r in perf} == {"umc", "constant"}
    fps = list(csv.DictReader(io.StringIO((folder / "false_positives.csv").read_text())))
    assert {r["controller"] for r in fps} == {"pec", "umc", "constant"}
    assert all(r["signals"] in ("0", "0.0") for r in fps if r["controller"] == "constant")
