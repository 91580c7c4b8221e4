"""The virtual study on a small configuration: the same server, worker and simulated
device as a live session, sped up; files are written and the tables have rows."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

from backend.analysis.virtual_study import QUESTIONNAIRE_NOTE, VirtualStudyConfig, run

pytestmark = pytest.mark.slow


def test_a_small_virtual_study_writes_its_tables_and_figures(tmp_path: Path) -> None:
    out = tmp_path / "vs"
    cfg = VirtualStudyConfig(out=out, participants=2, data_participants=2, eumc=1, seed=7,
                             speed=30.0, rates=("paper-rates",), margin_s=4.0)
    report = run(cfg, log=lambda _m: None)

    # UMC and PEC for both, E-UMC for the first: 5 trials, in counterbalanced order.
    assert [(t.participant, t.controller) for t in report.trials] == [
        ("P01", "umc"), ("P01", "pec"), ("P01", "eumc"), ("P02", "pec"), ("P02", "umc")]
    # Timed trials: one repetition of paper-evaluation plus the margin, exactly.
    from backend.analysis.virtual_study import _script_s

    for t, seed in zip(report.trials, (701, 701, 701, 702, 702), strict=True):
        assert t.ticks == round((_script_s(seed, "paper-evaluation") + 4.0) * 100)
        assert t.gaps == 0
    assert report.trials[2].calibration_attempts >= 1

    folder = out / "paper-rates"
    for name in ("performance.csv", "performance.md", "false_positives.csv",
                 "false_positives.md", "onset_to_lock.csv", "lifts.csv",
                 "peak_torques.png", "peak_torques.svg", "onset_to_lock.png"):
        assert (folder / name).stat().st_size > 0, name
    assert (folder / "peak_torques.png").read_bytes()[:4] == b"\x89PNG"
    assert list(folder.glob("timeline-trial-*.svg"))
    assert not (folder / "questionnaires.csv").exists()
    assert (out / "study.db").stat().st_size > 1_000_000

    perf = list(csv.DictReader(io.StringIO((folder / "performance.csv").read_text())))
    assert {(r["participant"], r["controller"]) for r in perf} == {
        ("P01", "umc"), ("P01", "eumc"), ("P02", "umc")}
    assert all(int(r["lifts"]) >= 9 for r in perf)  # ten squats, ten stoops per trial
    fps = list(csv.DictReader(io.StringIO((folder / "false_positives.csv").read_text())))
    assert {r["trial"] for r in fps} == {"walking", "stair_walking"}
    assert {r["controller"] for r in fps} == {"umc", "pec", "eumc"}
    lifts = list(csv.DictReader(io.StringIO((folder / "lifts.csv").read_text())))
    assert {r["kind"] for r in lifts} == {"squat", "stoop_left", "stoop_right"}

    models = json.loads((out / "models.json").read_text())
    assert models["format"] == "exostudy.motion_model_set"
    assert json.loads((out / "utilities.json").read_text())
    lopo = json.loads((out / "model_evaluation.json").read_text())
    assert lopo["participants"] == ["D01", "D02"] and lopo["segments"] >= 36
    assert 0.0 <= lopo["recognition_accuracy"] <= 1.0
    readme = (out / "README.md").read_text()
    assert QUESTIONNAIRE_NOTE in readme and "Intent estimation" in readme
    summary = json.loads((out / "summary.json").read_text())
    assert summary["wall_s"] > 0 and len(summary["trials"]) == 5
