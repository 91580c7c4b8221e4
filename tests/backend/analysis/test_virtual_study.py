"""The virtual study on a small configuration: the same server, worker and simulated
device as a live session, sped up; files are written and the tables have rows, and the
replication's plain-SQL reader counts the study's database as the server did. With
`emg`, a smaller study (two participants, lifts only) records the simulated wearer's EMG
over LSL and reports its reduction by the springs; it runs the command's default two rate
settings, so it also shows that each rate setting's study fits its own sets."""

from __future__ import annotations

import csv
import io
import json
import sqlite3
from contextlib import closing
from pathlib import Path

import pytest

from backend.analysis.virtual_study import (
    DEFAULT_SPEED,
    QUESTIONNAIRE_NOTE,
    VirtualStudyConfig,
    VirtualStudyReport,
    run,
)

# Two virtual study runs through the live server (the EMG one records over LSL and has
# two rate settings): on a loaded shared machine they can pass the suite's 300 s default.
pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]


@pytest.fixture(scope="module")
def small_study(tmp_path_factory: pytest.TempPathFactory
                ) -> tuple[Path, VirtualStudyReport]:
    """Two evaluated participants (E-UMC for the first) and two data-collection ones,
    the paper's protocol alone: run once for the module's tests, each of which only
    reads it."""
    out = tmp_path_factory.mktemp("virtual") / "vs"
    cfg = VirtualStudyConfig(out=out, participants=2, data_participants=2, eumc=1, seed=7,
                             speed=DEFAULT_SPEED, rates=("paper-rates",), margin_s=4.0)
    return out, run(cfg, log=lambda _m: None)


@pytest.fixture(scope="module")
def emg_study(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, VirtualStudyReport]:
    """The EMG virtual study at its smallest: two participants, UMC, PEC and the two
    baselines, each trial the lifts alone. Both rate settings, as the command's default:
    EMG and baselines are the first's ("paper-rates"); the "100hz" study, UMC and PEC
    alone, is what `test_both_rate_settings_run_each_on_its_own_studys_sets` reads (one
    run serves both tests: a study run costs a server, a data collection and fits)."""
    out = tmp_path_factory.mktemp("virtual") / "vs-emg"
    cfg = VirtualStudyConfig(out=out, participants=2, data_participants=2, eumc=0, seed=7,
                             speed=DEFAULT_SPEED, rates=("paper-rates", "100hz"), margin_s=4.0,
                             eval_script="lift-evaluation", model_evaluation=False,
                             emg=True)
    return out, run(cfg, log=lambda _m: None)


def test_a_small_virtual_study_writes_its_tables_and_figures(
        small_study: tuple[Path, VirtualStudyReport]) -> None:
    out, report = small_study

    # The paper's protocol alone (no baselines without `emg`): UMC and PEC for both,
    # counterbalanced, E-UMC after them for the first.
    got = [(t.participant, t.controller) for t in report.trials]
    assert sorted(got) == [("P01", "eumc"), ("P01", "pec"), ("P01", "umc"), ("P02", "pec"),
                           ("P02", "umc")]
    assert [p for p, _c in got] == ["P01"] * 3 + ["P02"] * 2 and got[2] == ("P01", "eumc")
    # Timed trials: one repetition of the paper's evaluation plus the margin, exactly.
    from backend.analysis.virtual_study import script_duration_s

    for t in report.trials:
        seed = 700 + int(t.participant[1:])
        assert t.ticks == round((script_duration_s(seed, "paper-evaluation") + 4.0) * 100)
        assert t.gaps == 0
    assert report.trials[2].calibration_attempts >= 1  # P01's E-UMC
    assert not (out / "paper-rates" / "muscle_results.json").exists()
    assert not (out / "emg").exists()

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


def test_muscle_activity_is_recorded_from_lsl_and_reduced_by_the_springs(
        emg_study: tuple[Path, VirtualStudyReport]) -> None:
    """The simulated amplifier's EMG went through LSL, the server's inlet and the store;
    every lift has its EMG, and the springs lower the back and hip extensors' activity
    against no exoskeleton, while the two baselines agree (the simulation models no
    device mass). EMG and baselines are the first rate setting's study's alone."""
    out, report = emg_study
    assert sorted(t.controller for t in report.trials if t.study == "paper-rates") == [
        "no_exoskeleton", "no_exoskeleton", "pec", "pec", "springs_free", "springs_free",
        "umc", "umc"]
    folder = out / "paper-rates"
    doc = json.loads((folder / "muscle_results.json").read_text())
    assert doc["method"]["normalisation"] == "task_peak"
    assert doc["method"]["processing"]["notch_hz"] == 50
    assert doc["baselines"] == ["springs_free", "no_exoskeleton"]
    assert len(doc["channels"]) == 12
    # Every lift is listed and measured: the study records its own simulator's stream
    # (by source id), and no sample of it is lost on the way.
    for t in doc["trials"]:
        assert t["recordings"] and t["lifts"] >= 18 and t["lifts_without_emg"] == 0, t
    reds = {(r["condition"], r["baseline"], r["channel"]): r for r in doc["reductions"]
            if r["group"] == "all" and r["metric"] == "mean"}
    for side in ("left", "right"):
        for ctl in ("umc", "pec"):
            r = reds[(ctl, "no_exoskeleton", f"erector_spinae_lumbar_{side}")]
            assert r["n"] == 2 and r["mean_pct"] > 5.0, r
            assert r["ci_low"] is not None and r["ci_low"] < r["mean_pct"] < r["ci_high"]
            assert r["test"].startswith("one-sample t-test")
        same = reds[("springs_free", "no_exoskeleton", f"erector_spinae_lumbar_{side}")]
        assert abs(same["mean_pct"]) < 5.0, same
    lifts = list(csv.DictReader(line for line in io.StringIO(
        (folder / "muscle_lifts.csv").read_text()) if not line.startswith("#")))
    assert {r["condition"] for r in lifts} == {"umc", "pec", "springs_free",
                                               "no_exoskeleton"}
    assert not [r for r in lifts if "samples_missing" in r["flags"] or "no_emg" in r["flags"]]
    assert all(r["flags"] == "" or "rate_mismatch" in r["flags"] for r in lifts[:50])
    for name in ("muscle_envelopes.png", "muscle_reduction.svg", "muscle_summary.csv",
                 "muscle_repeated_measures.csv"):
        assert (folder / name).stat().st_size > 0, name
    readme = (out / "README.md").read_text()
    assert "### Muscle activity" in readme and "Reduction of the mean envelope" in readme
    assert not (out / "100hz" / "muscle_results.json").exists()


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
    # Every measure at its smallest; with `from_db`, `participants` sizes only the muscle
    # section's EMG cohort (as small as `test_replication.py`'s).
    rep = replicate(ReplicationConfig(out=tmp_path / "rep", from_db=(out / "study.db",) * 2,
                                      participants=2, eumc=1, offset_participants=4,
                                      stair_participants=2, personalisation_participants=0),
                    log=lambda _m: None)
    assert [s.source for s in rep.seeds] == ["from-db", "from-db"]
    assert (tmp_path / "rep" / "report.html").is_file()


def test_both_rate_settings_run_each_on_its_own_studys_sets(
        emg_study: tuple[Path, VirtualStudyReport]) -> None:
    """The command's default, two rate settings as two studies: a trial must take its
    model and utility sets from its participant's study, so each study fits its own
    (the default run once failed at its first 100 Hz trial with a 409). The EMG study's
    run is such a study (lifts only); the "100hz" study has UMC and PEC alone."""
    out, report = emg_study
    assert sorted(report.studies) == ["100hz", "paper-rates"]
    got = sorted((t.study, t.participant, t.controller) for t in report.trials
                 if t.study == "100hz")
    assert got == [("100hz", "P01", "pec"), ("100hz", "P01", "umc"),
                   ("100hz", "P02", "pec"), ("100hz", "P02", "umc")]
    assert {t.study for t in report.trials} == {"100hz", "paper-rates"}
    assert all(t.gaps == 0 and t.ticks > 0 for t in report.trials)
    for label in report.studies:
        assert (out / label / "performance.csv").stat().st_size > 0
    # Each study fitted its own sets, and each trial ran on its own study's.
    with closing(sqlite3.connect(out / "study.db")) as db:
        for table in ("model_sets", "utility_sets"):
            assert sorted(db.execute(f"SELECT study_id FROM {table}")) == sorted(
                (sid,) for sid in report.studies.values()), table
        rows = {r[0]: r[1:] for r in db.execute(
            "SELECT t.id, p.study_id, m.study_id, u.study_id FROM trials t"
            " JOIN study_sessions s ON t.session_id = s.id"
            " JOIN participants p ON s.participant_id = p.id"
            " LEFT JOIN model_sets m ON t.model_set_id = m.id"
            " LEFT JOIN utility_sets u ON t.utility_set_id = u.id")}
    for t in report.trials:
        if t.controller == "umc":
            assert rows[t.trial_id] == (report.studies[t.study],) * 3, t
