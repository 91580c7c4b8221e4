"""The virtual personalisation study (docs/personalisation.md, "Virtual evidence"): a
tiny configuration, checked on structure and on values that can fail."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from controller.controllers.factory import make_from_spec
from controller.controllers.spec import ControllerSpec
from controller.evaluation.cohort import default_utilities
from controller.evaluation.personalisation import (
    EVAL_DAY_REPETITION,
    POPULATION,
    PersonalisationConfig,
    PersonalisationStudy,
    collect_participant,
    population_set,
    simulate_study,
)
from controller.evaluation.personalisation_report import (
    SECTION_TITLE,
    analysis_json,
    day_changes,
    lab_changes,
    section_markdown,
    t_interval,
    write_outputs,
)
from controller.evaluation.working_day import (
    confirmed_motions,
    day_recording,
    working_day_script,
)
from controller.runner.replay import replay_columns
from controller.sim.participant import VirtualParticipant
from controller.sim.scripts import realise

CFG = PersonalisationConfig(participants=4, seeds=(1,), demo_counts=(0, 3, 10),
                            priors_with=10, day_blocks=3)


@pytest.fixture(scope="module")
def study() -> PersonalisationStudy:
    return simulate_study(CFG)


def _same(a: dict[str, float], b: dict[str, float]) -> bool:
    return a.keys() == b.keys() and all(
        (math.isnan(a[k]) and math.isnan(b[k])) or a[k] == b[k] for k in a)


def test_every_condition_runs_for_every_participant(study: PersonalisationStudy) -> None:
    assert len(study.outcomes) == 4
    assert CFG.conditions() == ("population", "map-0", "map-3", "map-10", "own-3", "own-10",
                                "population+priors", "map-10+priors")
    for o in study.outcomes:
        assert set(o.lab) == {"umc", "eumc"}
        assert o.own_refused == ()
        assert o.personal_available == {"squat": 10, "stoop_left": 10, "stoop_right": 10}
        for conds in o.lab.values():
            assert set(conds) == set(CFG.conditions())
            assert all(0.0 <= m["correct_pct"] <= 100.0 for m in conds.values())


def test_no_demonstrations_is_exactly_the_population(study: PersonalisationStudy) -> None:
    for o in study.outcomes:
        for conds in o.lab.values():
            assert _same(conds["map-0"], conds[POPULATION])
    for c in lab_changes(study):
        if c.condition == "map-0":
            assert (c.change, c.ci_low, c.ci_high) == (0.0, 0.0, 0.0)
            assert c.mean_condition == c.mean_reference


def test_personal_demonstrations_change_some_decisions(study: PersonalisationStudy) -> None:
    """Ten own demonstrations per motion must move at least one participant's UMC
    result; a study where nothing changes would be measuring nothing."""
    diffs = [not _same(o.lab["umc"]["map-10"], o.lab["umc"][POPULATION])
             for o in study.outcomes]
    assert any(diffs)


def test_changes_are_the_participants_mean_difference(study: PersonalisationStudy) -> None:
    d = np.array([o.lab["umc"]["map-10"]["correct_pct"] - o.lab["umc"][POPULATION]
                  ["correct_pct"] for o in study.outcomes])
    c = next(c for c in lab_changes(study)
             if (c.controller, c.condition, c.metric) == ("umc", "map-10", "correct_pct"))
    assert c.n == 4
    assert c.change == pytest.approx(d.mean())
    assert c.per_seed == pytest.approx((d.mean(),))
    for ch in [*lab_changes(study), *day_changes(study)]:
        if math.isfinite(ch.ci_low):
            assert ch.ci_low <= ch.change <= ch.ci_high


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-100, 100), min_size=2, max_size=40))
def test_t_interval_is_students(x: list[float]) -> None:
    m, lo, hi = t_interval(np.array(x))
    a = np.array(x)
    assert m == pytest.approx(a.mean())
    if a.std() > 1e-9:
        ref = stats.t.interval(0.95, a.size - 1, loc=a.mean(), scale=stats.sem(a))
        assert (lo, hi) == pytest.approx(ref, abs=1e-9)
    assert lo <= m + 1e-12 and m <= hi + 1e-12


def test_population_sets_leave_the_participant_out() -> None:
    data = [collect_participant(CFG, 1, j) for j in range(3)]
    sets = [population_set(data, j) for j in range(3)]
    for j, ms in enumerate(sets):
        ids = [i for v in ms.demonstrations.values() for i in v]
        assert not any(f"seed={data[j].participant_seed}:" in i for i in ids)
        others = [d.participant_seed for d in data if d.index != j]
        assert all(any(f"seed={s}:" in i for i in ids) for s in others)
        assert ms["squat"].n_demonstrations == sum(len(d.pool["squat"]) for d in data
                                                   if d.index != j)
    assert not np.array_equal(sets[0]["squat"].mean, sets[1]["squat"].mean)


def test_confirmed_motions_are_lifts_and_gait_bouts() -> None:
    acts = ["stand", "walk", "turn", "stairs_up", "stand", "squat", "squat", "stand",
            "stoop_left", "stand", "walk", "stand"]
    assert confirmed_motions(acts) == ["other", "squat", "stoop_left", "other"]
    p = VirtualParticipant.from_seed(3)
    traj = realise(working_day_script(3), p, 3, 0)
    motions = confirmed_motions(traj.activity_names().tolist())
    assert motions.count("other") == 9  # 3 blocks: stairs, walk, stairs
    assert [motions.count(k) for k in ("squat", "stoop_left", "stoop_right")] == [2, 2, 2]
    assert traj.n_lifts == 6


def _stair_signals_from_ticks(cols: dict[str, np.ndarray]) -> int:
    """Rising edges of the held command (either side) inside gait runs of at least 5 s
    that hold a stair tick, counted here without the evaluation package."""
    held = np.asarray(cols["lock_left"], bool) | np.asarray(cols["lock_right"], bool)
    rise = held & ~np.concatenate([[False], held[:-1]])
    act = np.asarray(cols["truth_activity"]).astype(str)
    t = np.asarray(cols["t"], dtype=np.float64)
    gait = np.isin(act, ["walk", "turn", "stairs_up", "stairs_down"])
    total, k = 0, 0
    while k < len(gait):
        if not gait[k]:
            k += 1
            continue
        e = k
        while e + 1 < len(gait) and gait[e + 1]:
            e += 1
        if t[e] - t[k] >= 5.0 and np.isin(act[k:e + 1], ["stairs_up", "stairs_down"]).any():
            total += int(rise[k:e + 1].sum())
        k = e + 1
    return total


def test_stairs_day_counts_match_the_ticks(study: PersonalisationStudy) -> None:
    o = study.outcomes[0]
    data = [collect_participant(CFG, 1, j) for j in range(CFG.participants)]
    models = population_set(data, 0)
    utilities = default_utilities(CFG.precompression_pct)
    p = VirtualParticipant.from_seed(o.participant_seed)
    rec = day_recording(p, o.participant_seed, CFG.day_blocks, EVAL_DAY_REPETITION)
    held = {}
    for which, pr in (("equal", None), ("learned", o.priors)):
        spec = ControllerSpec("umc", CFG.settings(), models=models.to_json(),
                              utilities=utilities.to_json(), priors=pr)
        cols = replay_columns(rec, make_from_spec(spec), CFG.precompression_pct)
        assert o.day[which]["fp_stairs"] == _stair_signals_from_ticks(cols)
        assert o.day[which]["lifts"] == 2 * CFG.day_blocks
        held[which] = np.asarray(cols["lock_left"], bool) | np.asarray(cols["lock_right"], bool)
    # The safety bound: learned priors never hold a lock that equal priors do not.
    assert not (held["learned"] & ~held["equal"]).any()
    assert o.priors.values != o.priors.estimate or o.priors.bounds.contains(o.priors.values)
    assert o.priors.values[3] > 0.25  # a gait-heavy day raises "other"


def test_outputs_and_report_section(study: PersonalisationStudy, tmp_path: Path) -> None:
    written = write_outputs(study, tmp_path / "out")
    names = [p.name for p in written]
    for name in ("lab_changes.csv", "lab_changes.md", "curve.csv", "curve.png",
                 "stairs_day.csv", "stairs_day.md", "personalisation.json", "README.md"):
        assert name in names
    assert (tmp_path / "out" / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    curve = (tmp_path / "out" / "curve.csv").read_text().splitlines()
    assert curve[0].startswith("controller,condition,reference,metric,n,")
    assert len(curve) == 1 + 2 * 5  # per controller: map-0, map-3, own-3, map-10, own-10
    doc = json.loads((tmp_path / "out" / "personalisation.json").read_text())
    assert doc == json.loads(json.dumps(analysis_json(study)))
    md = section_markdown(doc)
    assert md.startswith(f"## {SECTION_TITLE}\n")
    assert md.count("| MAP-adapted, 0 demos/motion | ") == 2
    assert "0.00 [0.00, 0.00]" in md
    day = next(c for c in day_changes(study) if c.metric == "fp_stairs")
    assert f"{day.change:.2f} [{day.ci_low:.2f}, {day.ci_high:.2f}]" in md
    with pytest.raises(ValueError, match="personalisation"):
        section_markdown({"format": "exostudy.cohort"})


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"controllers": ("pec",)}, "controllers"),
    ({"priors_with": 4}, "priors_with"),
    ({"demo_counts": (3, 0)}, "demo_counts"),
    ({"demo_counts": (0, 11)}, "demo_counts"),
    ({"participants": 2}, "participants"),
    ({"seeds": (1, 1)}, "seeds"),
])
def test_bad_configurations_are_named(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        PersonalisationConfig(**kwargs)  # type: ignore[arg-type]
