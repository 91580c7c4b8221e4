"""A small virtual cohort end to end: participants from seeds, one trial per controller
through the batch replay kernel, every metric, the statistics and the files."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from controller.decision.utility_function import UtilitySet
from controller.evaluation.cohort import (
    METRIC_NAMES,
    CohortConfig,
    simulate_cohort,
    simulate_participant,
    trial_recording,
)
from controller.evaluation.cohort_report import analyse, write_outputs
from controller.intent.motion_model import ModelSet
from controller.sim.participant import VirtualParticipant

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def sets(default_sets: tuple[Path, Path]) -> tuple[ModelSet, UtilitySet]:
    models, folder = default_sets
    return ModelSet.load(models), UtilitySet.load(next(folder.glob("utilities-*.json")))


def test_config_refuses_what_it_cannot_simulate() -> None:
    with pytest.raises(ValueError, match="participants"):
        CohortConfig(participants=1)
    with pytest.raises(ValueError, match="controllers"):
        CohortConfig(controllers=("umc", "lqr"))
    with pytest.raises(ValueError, match="rate_hz"):
        CohortConfig(rate_hz=500.0)
    cfg = CohortConfig(seed=2)
    # Away from the default demonstrators' seeds (101..106), distinct per participant.
    assert cfg.participant_seed(0) == 1_020_000 and cfg.participant_seed(7) == 1_020_007


def test_trials_differ_per_controller_and_see_the_donning_offset() -> None:
    p = VirtualParticipant.from_seed(1_010_003)
    a = trial_recording(p, p.seed, "paper-evaluation", 0)
    b = trial_recording(p, p.seed, "paper-evaluation", 1)
    assert a.t.size != b.t.size or not np.allclose(a.q, b.q)  # a new repetition each
    stand = np.asarray(a.activity) == "stand"
    # What the encoders see while standing: true flexion plus the donning offset.
    offset = np.radians(p.offset_deg)
    measured = a.q[stand][:50].mean(axis=0)
    assert np.allclose(measured - p.stand_flexion, offset, atol=np.radians(1.5))


def test_participant_metrics_are_consistent_counts(sets: tuple[ModelSet, UtilitySet]) -> None:
    cfg = CohortConfig(participants=2, seed=1)
    r = simulate_participant(cfg, 0, *sets)
    assert set(r.metrics) == {"umc", "eumc", "pec"}
    assert r.calibration_attempts >= 1
    for c, m in r.metrics.items():
        assert set(m) == set(METRIC_NAMES)
        lifts = 20  # ten squats and ten stoops in paper-evaluation
        correct = round(m["correct_pct"] * lifts / 100)
        assert correct + m["wrong"] + m["missed"] == lifts, c
        assert m["fp_total"] == m["fp_walking"] + m["fp_stairs"]
    assert math.isnan(r.metrics["pec"]["recognised_pct"])  # no intent estimation
    assert 0 <= r.metrics["umc"]["recognised_pct"] <= 100
    # The PEC locks both hips in every lift: its squats are all "correct".
    assert r.metrics["pec"]["correct_sq_pct"] == 100.0
    # Deterministic in the seed.
    assert simulate_participant(cfg, 0, *sets).metrics["umc"] == r.metrics["umc"]


def test_small_cohort_writes_tables_figures_and_json(sets: tuple[ModelSet, UtilitySet],
                                                     tmp_path: Path) -> None:
    seen: list[float] = []
    cohort = simulate_cohort(CohortConfig(participants=4, seed=3,
                                          controllers=("umc", "pec")), *sets,
                             progress=seen.append)
    assert seen[-1] == 1.0 and seen == sorted(seen)
    analysis = analyse(cohort, sizes=(4, 8), resamples=200)
    paths = write_outputs(cohort, analysis, tmp_path)
    names = {p.name for p in paths}
    assert {"participants.csv", "metrics.csv", "metrics.md", "comparisons.csv",
            "comparisons.md", "power.csv", "power.png", "power.svg", "distributions.png",
            "cohort.json", "README.md"} <= names
    assert (tmp_path / "power.png").read_bytes()[:4] == b"\x89PNG"
    rows = list(csv.DictReader(io.StringIO((tmp_path / "participants.csv").read_text())))
    assert len(rows) == 8 and {r["controller"] for r in rows} == {"umc", "pec"}
    doc = json.loads((tmp_path / "cohort.json").read_text())
    assert doc["format"] == "exostudy.cohort" and len(doc["participants"]) == 4
    fp = next(c for c in doc["comparisons"] if c["metric"] == "fp_total")
    assert (fp["a"], fp["b"]) == ("umc", "pec") and len(fp["power"]) == 2
    # The mean difference in the JSON is the one the per-participant table gives.
    by = {(r["participant"], r["controller"]): float(r["fp_total"]) for r in rows}
    diff = np.mean([by[(str(i), "umc")] - by[(str(i), "pec")] for i in range(1, 5)])
    assert fp["mean_diff"] == pytest.approx(diff)
    assert "only as good as the simulated population" in (tmp_path / "README.md").read_text()


def test_processes_give_the_same_cohort(sets: tuple[ModelSet, UtilitySet]) -> None:
    cfg = CohortConfig(participants=3, seed=5, controllers=("pec", "umc"))
    one = simulate_cohort(cfg, *sets)
    two = simulate_cohort(cfg, *sets, processes=2)
    # NaN-aware: the PEC's recognised_pct is NaN in both.
    assert (json.dumps([p.metrics for p in two.participants], sort_keys=True)
            == json.dumps([p.metrics for p in one.participants], sort_keys=True))
    assert [p.seed for p in two.participants] == [cfg.participant_seed(j) for j in range(3)]
