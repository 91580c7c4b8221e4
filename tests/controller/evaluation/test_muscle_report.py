"""The cohort's muscle-activity report on a cohort whose reductions are known by
construction: every controller's activity is a fixed fraction of the baseline's."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from controller.evaluation.cohort import Cohort, CohortConfig, ParticipantResult
from controller.evaluation.cohort_report import analysis_json, from_json
from controller.evaluation.muscle_activity import (
    LABELS,
    OUTCOMES,
    TASKS,
    ConditionMuscles,
    ParticipantMuscles,
)
from controller.evaluation.muscle_report import analyse_muscles, markdown, write_outputs
from controller.evaluation.output_folder import OutputFolder

#: Activity of each condition as a fraction of "no exoskeleton".
FRACTION = {"umc": 0.8, "eumc": 0.75, "pec": 0.7, "springs_free": 1.0, "no_exoskeleton": 1.0}


def _cohort(n: int = 5) -> Cohort:
    cfg = CohortConfig(participants=n, emg=True)
    people = []
    rng = np.random.default_rng(1)
    for j in range(n):
        level = float(rng.uniform(0.2, 0.6))
        conds = {}
        for cond, f in FRACTION.items():
            out = {t: {o: {ch: level * f * (1.0 + 0.01 * j) for ch in LABELS}
                       for o in OUTCOMES} for t in TASKS}
            cycle = {ch: list(level * f * np.sin(np.linspace(0, np.pi, 101))) for ch in LABELS}
            conds[cond] = ConditionMuscles(cond, 20, out, out, cycle, 30.0 * (f < 1.0))
        people.append(ParticipantResult(j, 100 + j, {}, {c: {} for c in cfg.controllers},
                                        0, ParticipantMuscles({ch: 1e-3 for ch in LABELS},
                                                              conds)))
    return Cohort(cfg, people)


def test_reductions_are_the_constructed_fractions() -> None:
    a = analyse_muscles(_cohort())
    assert a is not None
    assert a.baselines == ("no_exoskeleton", "springs_free")
    for outcome in OUTCOMES:
        rs = a.reductions[(outcome, "no_exoskeleton")]
        assert len(rs) == len(LABELS) * 4  # 3 controllers and the other baseline
        for r in rs:
            want = 100.0 * (1.0 - FRACTION[r.condition])
            assert r.mean_pct == pytest.approx(want, abs=1e-9)
            assert r.n == 5
            # No spread (up to rounding): the t-test's limit.
            assert r.p_holm == pytest.approx(1.0 if want == 0 else 0.0, abs=1e-9)
        assert [r.mean_pct for r in a.truth[(outcome, "no_exoskeleton")]] == pytest.approx(
            [r.mean_pct for r in rs])
        assert all(r.test.startswith("Friedman") for r in a.repeated[outcome])
    text = markdown(a, 5)
    assert "| erector_spinae_lumbar_left | 20.0 [20.0, 20.0], p_Holm " in text
    assert "Holm over 48 channel x condition comparisons" in text


def test_outputs_are_written_and_survive_cohort_json(tmp_path: Path) -> None:
    cohort = _cohort()
    folder = OutputFolder(tmp_path)
    section = write_outputs(cohort, folder.put)
    names = {p.name for p in folder.written}
    assert {"muscle_reductions.csv", "muscle_repeated.md", "muscle_envelope.png",
            "muscle_reduction.svg", "muscles.json"} <= names
    assert section.startswith("\n## Muscle activity")
    doc = json.loads((tmp_path / "muscles.json").read_text())
    row = next(r for r in doc["reductions"] if r["condition"] == "pec"
               and r["baseline"] == "no_exoskeleton" and r["outcome"] == "peak")
    assert math.isclose(row["mean_pct"], 30.0)
    # Through cohort.json (the console's stored form) and back.
    from controller.evaluation.cohort_report import CohortAnalysis

    back, _ = from_json(json.loads(json.dumps(analysis_json(cohort, CohortAnalysis((), ())))))
    assert back.config.emg
    assert back.participants[2].muscles == cohort.participants[2].muscles


def test_no_muscle_data_writes_nothing(tmp_path: Path) -> None:
    cohort = Cohort(CohortConfig(participants=2), [])
    folder = OutputFolder(tmp_path)
    assert write_outputs(cohort, folder.put) == "" and folder.written == []
