"""The paper's tables: counts, layout, CSV and Markdown."""

from __future__ import annotations

import csv
import io

import pytest

from controller.evaluation.study import RecordingEvaluation
from controller.evaluation.tables import (
    FalsePositiveTable,
    PerformanceTable,
    QuestionnaireScore,
    QuestionnaireTable,
    Table,
    lift_table,
    onset_to_lock_table,
)

from .tick_builder import gait_recording, lifting_recording


def parse(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


@pytest.fixture(scope="module")
def study() -> list[RecordingEvaluation]:
    return [
        lifting_recording("1", "umc", good=False),
        lifting_recording("1", "pec", good=True, intent=False),
        lifting_recording("2", "umc", good=True),
        lifting_recording("2", "eumc", good=False),
        gait_recording("1", "umc", 3, "walking"),
        gait_recording("1", "umc", 1, "stair_walking"),
        gait_recording("1", "pec", 0, "walking"),
        gait_recording("2", "umc", 2, "stair_walking"),
        gait_recording("2", "eumc", 0, "stair_walking"),
    ]


def test_performance_counts(study: list[RecordingEvaluation]) -> None:
    t = PerformanceTable.from_evaluations(study)
    rows = {(r.participant, r.controller, r.motion): r for r in t.rows}
    bad_sq, bad_as = rows[("1", "umc", "SQ")], rows[("1", "umc", "AS")]
    assert (bad_sq.lifts, bad_sq.recognised, bad_sq.correct, bad_sq.wrong, bad_sq.missed) == (
        2, 1, 1, 0, 1
    )
    assert (bad_as.lifts, bad_as.recognised, bad_as.correct, bad_as.wrong, bad_as.missed) == (
        2, 1, 1, 1, 0
    )
    assert rows[("2", "umc", "SQ")].correct == 2
    assert t.controllers == ("umc", "pec", "eumc")
    by_kind = PerformanceTable.from_evaluations(study, by_kind=True)
    assert by_kind.motions == ("squat", "stoop_left", "stoop_right")


def test_performance_paper_layout(study: list[RecordingEvaluation]) -> None:
    t = PerformanceTable.from_evaluations(study, controllers=("umc", "eumc"))
    wide = t.wide()
    assert wide.header == ("Metric", "Motion", "1", "2")
    cells = {(r[0], r[1]): r[2:] for r in wide.rows}
    assert cells[("Intent estimation", "SQ")] == ("1", "2/1")
    assert cells[("Intent estimation", "AS")] == ("1", "2/1")
    assert cells[("Decision correct", "SQ")] == ("1", "2/1")
    assert cells[("Decision missed", "SQ")] == ("1", "0/1")
    md = t.to_markdown()
    assert "| Intent estimation | SQ | 1 | 2/1 |" in md
    assert "UMC/E-UMC" in md
    rows = parse(t.to_csv())
    assert rows[0] == {"participant": "1", "controller": "umc", "motion": "SQ", "lifts": "2",
                       "recognised": "1", "correct": "1", "wrong": "0", "missed": "1",
                       "first_correct": "1", "first_one_sided": "0"}
    assert cells[("First decision correct", "AS")] == ("1", "2/1")
    assert ("First lock one-sided", "AS") not in cells
    # A column a participant did not run keeps the others under their own: left out at
    # the end (participant 1, no E-UMC), a dash inside (participant 2, no PEC).
    mixed = PerformanceTable.from_evaluations(study, controllers=("umc", "pec", "eumc"))
    cells = {(r[0], r[1]): r[2:] for r in mixed.wide().rows}
    assert cells[("Decision correct", "SQ")] == ("1/2", "2/\u2013/1")
    assert cells[("Intent estimation", "SQ")] == ("1/-", "2/\u2013/1")  # the PEC: no intent
    pec = PerformanceTable.from_evaluations(study, controllers=("pec",))
    assert pec.rows[0].recognised is None
    assert "| Intent estimation | SQ | - |" in pec.to_markdown()
    assert parse(pec.to_csv())[0]["recognised"] == ""


def test_false_positive_table(study: list[RecordingEvaluation]) -> None:
    t = FalsePositiveTable.from_evaluations(study, controllers=("pec", "umc", "eumc"))
    cells = {(r[0], r[1]): r[2:] for r in t.wide().rows}
    assert cells[("PEC", "W")] == ("0", "/")
    assert cells[("UMC", "W")] == ("3", "/")
    assert cells[("UMC", "SW")] == ("1", "2")
    assert cells[("E-UMC", "SW")] == ("/", "0")
    rows = parse(t.to_csv())
    umc_w = next(r for r in rows if r["controller"] == "umc" and r["trial"] == "walking")
    assert (umc_w["signals"], umc_w["decisions"], umc_w["lock_ticks"]) == ("3", "3", "90")
    assert float(umc_w["duration_s"]) == pytest.approx(19.99)
    assert "| UMC | SW | 1 | 2 |" in t.to_markdown()


def test_lift_and_onset_tables(study: list[RecordingEvaluation]) -> None:
    rows = parse(lift_table(study).to_csv())
    assert len(rows) == 16
    missed = rows[1]
    assert (missed["kind"], missed["decision"], missed["first_action"]) == (
        "squat", "missed", ""
    )
    assert (missed["peak_torque_left_nm"], missed["peak_torque_right_nm"]) == ("11.0", "21.0")
    assert rows[2]["first_action"] == "lock_both" and rows[2]["decision"] == "wrong"
    assert (rows[2]["first_decision"], rows[2]["sides_commanded"]) == ("wrong", "LR")
    onset = parse(onset_to_lock_table(study).to_csv())
    umc_all = next(r for r in onset if r["controller"] == "UMC" and r["motion"] == "all")
    assert (umc_all["lifts"], umc_all["first_locked"]) == ("8", "7")
    assert float(umc_all["first_median_s"]) == pytest.approx(0.30)


# The paper's questionnaire table (participants 1-8).
SUS = {"pec": (72.5, 97.5, 72.5, 82.5, 62.5, 92.5, 80, 75),
       "umc": (75, 95, 80, 80, 70, 95, 77.5, 70)}
EUS = {"pec": (6.35, 7.8, 7.1, 8.4, 6.45, 8.4, 4.95, 6.6),
       "umc": (6.35, 7.95, 7.95, 7.95, 6.25, 8.15, 5.65, 5.95)}
PREFERENCE = {"4": "pec", "5": "pec", "6": "PEC", "7": "umc", "1": "no preference"}


def paper_questionnaires() -> QuestionnaireTable:
    scores = [
        QuestionnaireScore(str(i + 1), c, name, float(v))
        for name, table in (("SUS", SUS), ("EUS", EUS))
        for c, values in table.items()
        for i, v in enumerate(values)
    ]
    return QuestionnaireTable.from_scores(scores, PREFERENCE)


def test_questionnaire_table_reproduces_the_papers_bold_marks() -> None:
    md = paper_questionnaires().to_markdown()
    assert "| Instrument | Controller | 1 | 2 | 3 | 4 | 5 | 6 | 7 | 8 |" in md
    assert "| SUS | PEC | 72.5 | **97.5** | 72.5 | **82.5** | 62.5 | 92.5 | **80** | **75** |" in md
    assert "| SUS | UMC | **75** | 95 | **80** | 80 | **70** | **95** | 77.5 | 70 |" in md
    # Participant 1's tie (6.35 / 6.35) is marked on neither side, as in the paper.
    assert "| EUS | PEC | 6.35 | 7.8 | 7.1 | **8.4** | **6.45** | **8.4** | 4.95 | **6.6** |" in md
    assert "| EUS | UMC | 6.35 | **7.95** | **7.95** | 7.95 | 6.25 | 8.15 | **5.65** | 5.95 |" in md
    assert "| Preference |  | / | / | / | PEC | PEC | PEC | UMC | / |" in md


def test_questionnaire_csv_and_checks() -> None:
    t = paper_questionnaires()
    rows = parse(t.to_csv())
    assert len(rows) == 32
    p7 = [r for r in rows if r["participant"] == "7" and r["instrument"] == "EUS"]
    assert [(r["controller"], r["highest"]) for r in p7] == [("pec", "false"), ("umc", "true")]
    assert p7[0]["stated_preference"] == "umc"
    assert t.highest("1", "EUS") is None and t.highest("1", "SUS") == "umc"
    single = QuestionnaireTable.from_scores([QuestionnaireScore("9", "umc", "SUS", 50.0)])
    assert single.highest("9", "SUS") is None  # nothing to compare with
    with pytest.raises(ValueError, match="two scores"):
        QuestionnaireTable.from_scores([QuestionnaireScore("1", "umc", "SUS", 50.0)] * 2)


def test_generic_table_rendering() -> None:
    t = Table(("a", "b|c"), (("x|y", 1.23456), (None, float("nan")), (True, 3)), title="T",
              notes=("note",))
    assert t.to_csv() == "a,b|c\nx|y,1.23456\n,\ntrue,3\n"
    assert t.to_markdown() == (
        "**T**\n\n| a | b\\|c |\n| --- | --- |\n| x\\|y | 1.235 |\n|  |  |\n| yes | 3 |\n\nnote\n"
    )
    with pytest.raises(ValueError, match="cells"):
        Table(("a",), (("x", "y"),))
