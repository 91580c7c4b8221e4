"""The virtual study on a small configuration: the same server, worker and simulated
device as a live session, sped up; files are written and the tables have rows, and the
replication's plain-SQL reader counts the study's database as the server did."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

from backend.analysis.virtual_study import (
    QUESTIONNAIRE_NOTE,
    VirtualStudyConfig,
    VirtualStudyReport,
    run,
)

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def small_study(tmp_path_factory: pytest.TempPathFactory
                ) -> tuple[Path, VirtualStudyReport]:
    """Two evaluated participants (E-UMC for the first) and two data-collection ones:
    run once for the module's tests, each of which only reads it."""
    out = tmp_path_factory.mktemp("virtual") / "vs"
    cfg = VirtualStudyConfig(out=out, participants=2, data_participants=2, eumc=1, seed=7,
                             speed=30.0, rates=("paper-rates",), margin_s=4.0)
    return out, run(cfg, log=lambda _m: None)


def test_a_small_virtual_study_writes_its_tables_and_figures(
        small_study: tuple[Path, VirtualStudyReport]) -> None:
    out, report = small_study

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


def test_the_replication_reader_counts_the_study_db_as_the_server_did(
        small_study: tuple[Path, VirtualStudyReport], tmp_path: Path) -> None:
    """The replication's plain-SQL reader against the server's own tables of the same
    virtual study, then a replication run from that database."""
    from backend.analysis.replication_config import ReplicationConfig
    from backend.analysis.replication_run import read_study_db
    from backend.analysis.replication_run import run as replicate

    out, _report = small_study
    trials, models, utilities = read_study_db(out / "study.db")
    assert sorted((e.participant, e.controller) for _c, e in trials) == [
        ("P01", "eumc"), ("P01", "pec"), ("P01", "umc"), ("P02", "pec"), ("P02", "umc")]
    assert models is not None and utilities is not None
    served = list(csv.DictReader(io.StringIO(
        (out / "paper-rates" / "performance.csv").read_text())))
    assert served
    for row in served:
        mine = [o for _c, e in trials for o in e.lifts
                if e.participant == row["participant"] and e.controller == row["controller"]
                and {"SQ": "squat"}.get(row["motion"], "stoop") in o.lift.kind]
        assert len(mine) == int(row["lifts"])
        assert sum(o.decision.value == "correct" for o in mine) == int(row["correct"])
        assert sum(bool(o.recognised) for o in mine) == int(row["recognised"])
    rep = replicate(ReplicationConfig(out=tmp_path / "rep", from_db=(out / "study.db",) * 2,
                                      offset_participants=4, stair_participants=2),
                    log=lambda _m: None)
    assert [s.source for s in rep.seeds] == ["from-db", "from-db"]
    assert (tmp_path / "rep" / "report.html").is_file()
