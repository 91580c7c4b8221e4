"""Per-seed measures and claim verdicts on hand-built trials whose answers are known."""

from __future__ import annotations

import math

import pytest

from controller.evaluation.columns import TickData
from controller.evaluation.lifts import GaitTrial, lifts_from_truth
from controller.evaluation.paper_claims import (
    CLAIMS,
    MARGIN_PER_10_LIFTS,
    MARGIN_PER_TRIAL,
    PAPER_FALSE_POSITIVES,
    PAPER_PERFORMANCE,
    Claim,
    judge,
    judge_all,
    paper_eumc_gain,
    paper_mean,
    seed_halves,
    seed_measures,
    trial_data,
)
from controller.evaluation.study import evaluate_recording
from controller.evaluation.verdicts import Verdict
from controller.tick_record import Action

from .tick_builder import TickBuilder


def lifting(participant: str, controller: str, plans: list[list[Action]]):  # type: ignore[no-untyped-def]
    """Two squats, a stoop left and a stoop right (ticks 100+200i .. 199+200i); lift i
    gets the decisions plans[i] at ticks start+10, start+20, ..."""
    b = TickBuilder(1000)
    kinds = ("squat", "squat", "stoop_left", "stoop_right")
    lifts = [b.lift(i, k, 100 + 200 * i, 199 + 200 * i) for i, k in enumerate(kinds)]  # type: ignore[arg-type]
    for lf, plan in zip(lifts, plans, strict=True):
        b.posterior(lf.start + 5, lf.kind, 0.9)
        for n, a in enumerate(plan):
            b.run(lf.start + 10 * (n + 1), a)
        b.torque(lf.start + 60, 10.0, 30.0 if lf.kind != "stoop_left" else 5.0)
    cols = b.columns()
    return TickData.of(cols), evaluate_recording(cols, participant, controller,
                                                 lifts_from_truth(cols))


L, R, B = Action.LOCK_LEFT, Action.LOCK_RIGHT, Action.LOCK_BOTH


def test_paper_transcription_means() -> None:
    assert paper_mean(PAPER_PERFORMANCE[("umc", "correct", "SQ")]) == pytest.approx(73 / 8)
    assert paper_mean(PAPER_FALSE_POSITIVES[("umc", "SW")]) == pytest.approx(106 / 8)
    # Participants 2, 3, 7: UMC 20, 11, 17 correct of 20; E-UMC 20 each.
    assert paper_eumc_gain() == pytest.approx((0 + 9 + 3) / 3)


def test_seed_measures_count_by_the_papers_rule_and_the_first_decision() -> None:
    umc = lifting("1", "umc", [[L, R], [B], [L], [B, R]])
    eumc = lifting("1", "eumc", [[B], [B], [L], [R]])
    pec = lifting("1", "pec", [[B], [], [B], [B]])
    m = seed_measures([trial_data(c, e) for c, e in (umc, eumc, pec)])
    assert m["umc.correct.SQ"] == 10.0  # both squats have both sides in the first half
    assert m["umc.first_correct.SQ"] == 5.0  # the first squat began one-sided
    assert m["umc.first_one_sided.SQ"] == 5.0
    assert m["umc.correct.AS"] == 5.0  # stoop right began with lock both: wrong
    assert m["umc.recognised.SQ"] == 10.0
    assert m["eumc.correct.AS"] == 10.0
    assert m["pec.correct.SQ"] == 5.0 and m["pec.engaged.AS"] == 10.0
    assert "pec.recognised.SQ" not in m
    # E-UMC 4/4, UMC 3/4 correct: 5 more per 20 lifts.
    assert m["eumc_minus_umc.correct20"] == pytest.approx(5.0)
    # Stoop left: supporting (left) 10 Nm against 5; stoop right 30 against 10.
    assert m["umc.stoop_support_share"] == pytest.approx((10 / 15 + 30 / 40) / 2)
    assert m["umc.squat_asymmetry"] == pytest.approx(20 / 40)


def test_false_positives_and_stair_posteriors() -> None:
    b = TickBuilder(2000)
    b.gait(100, 899, "walk")
    b.gait(1000, 1899, "stairs_up")
    b.run(300, R)  # one lock while walking
    for k in (1100, 1500):
        b.posterior(k, "stoop_right", 0.7)
        b.run(k, R)
    b.posterior(1600, "other", 0.8)
    b.run(1600, Action.NO_LOCK)
    for s in ("squat", "stoop_left", "stoop_right"):
        b.cols[f"s_curr_{s}"][:] = math.nan
    b.cols["s_curr_stoop_right"][1100] = 0.2
    b.cols["s_curr_stoop_right"][1500] = 0.45
    b.cols["s_curr_squat"][1500] = 0.5  # not the most probable model: ignored
    cols = b.columns()
    ev = evaluate_recording(cols, "1", "umc",
                            trials=[GaitTrial("walking", 100, 899),
                                    GaitTrial("stair_walking", 1000, 1899)])
    td = trial_data(TickData.of(cols), ev, online_end=0.5)
    assert td.max_progress == pytest.approx(0.45)
    assert td.stair_favoured == {"squat": 0, "stoop_left": 0, "stoop_right": 2, "other": 1}
    assert td.stair_lock_favoured["stoop_right"] == 2 and td.stair_lock_favoured["other"] == 0
    m = seed_measures([td])
    assert (m["fp.umc.W"], m["fp.umc.SW"], m["fp.umc.SW_minus_W"]) == (1.0, 2.0, 1.0)
    assert m["umc.max_progress"] == pytest.approx(0.9)
    assert m["umc.stair_lock_stoop_share"] == 1.0
    assert m["umc.stair_favoured.other"] == pytest.approx(1 / 3)


def test_judge_each_kind_of_claim() -> None:
    value = Claim("v", "Table", "a number", "x", "value", 9.375)
    assert judge(value, [8.0, 9.0, 10.0, 9.0, 9.0]).verdict is Verdict.REPRODUCED
    r = judge(value, [10.0] * 5)
    assert r.verdict is Verdict.DIFFERS and "below" in r.reason
    ordinal = Claim("o", "Discussion", "more", "x", "ordinal", threshold=0.5)
    assert judge(ordinal, [0.8, 0.85, 0.9]).verdict is Verdict.REPRODUCED
    assert judge(ordinal, [0.3, 0.85, 0.9]).verdict is Verdict.DIFFERS
    check = Claim("c", "Figure", "0.2771", "x", "check", 0.2771, tolerance=5e-5)
    assert judge(check, [0.27707]).verdict is Verdict.REPRODUCED
    assert judge(Claim("q", "Table", "scores", kind="not_simulated"), []).verdict \
        is Verdict.NOT_SIMULATED
    assert judge(value, [math.nan, math.nan]).verdict is Verdict.DIFFERS


def test_every_claim_is_judged_and_checks_come_from_checks() -> None:
    keys = [c.key for c in CLAIMS]
    assert len(keys) == len(set(keys))
    checks = {"utility_stoop_gap": 5.0, "value_iteration_gap": 0.0, "chi_square_tail": 0.2771,
              "actuator_violations": 0.0}
    res = judge_all([{}, {}], checks)
    assert len(res) == len(CLAIMS)
    by = {r.claim.key: r for r in res}
    assert by["chi_square"].verdict is Verdict.REPRODUCED
    assert by["questionnaires"].verdict is Verdict.NOT_SIMULATED
    assert by["umc.correct.SQ"].verdict is Verdict.DIFFERS  # no seed gave a value


def test_table_claims_are_judged_on_the_difference_with_the_papers_participants() -> None:
    by = {c.key: c for c in CLAIMS}
    walk = by["fp.umc.W"]
    assert walk.kind == "difference"
    assert walk.paper_values == (0.0, 0.0, 7.0, 0.0, 1.0, 0.0, 14.0, 0.0)
    assert walk.margin == MARGIN_PER_TRIAL == 1.0
    assert by["eumc.correct.AS"].paper_values == (10.0, 10.0, 10.0)
    assert by["umc.correct.AS"].margin == MARGIN_PER_10_LIFTS == 1.0
    assert by["umc_fp_walk_some"].paper_values == (0, 0, 1, 0, 1, 0, 1, 0)
    assert by["umc_fp_walk_some"].margin == 1 / 8
    for c in CLAIMS:
        if c.kind == "difference":
            assert c.paper == pytest.approx(sum(c.paper_values) / len(c.paper_values))
    with pytest.raises(ValueError, match="per-participant values"):
        Claim("x", "Table", "no values", "x", "difference", 1.0, margin=1.0)


def test_judge_a_difference_claim() -> None:
    walk = next(c for c in CLAIMS if c.key == "fp.umc.W")
    # Seeds 11-15 of the cohort engine gave about 0.75 with a narrow interval.
    r = judge(walk, [0.5, 0.75, 1.0, 0.625, 0.875])
    assert r.verdict is Verdict.INCONCLUSIVE and r.difference is not None
    assert r.difference.se_paper == pytest.approx(1.82, abs=0.005)
    assert "TOST" in r.reason and "margin" in r.reason
    stairs = next(c for c in CLAIMS if c.key == "fp.umc.SW")
    assert judge(stairs, [3.5, 1.3, 2.0, 4.1, 3.0]).verdict is Verdict.DIFFERS
    zero = next(c for c in CLAIMS if c.key == "fp.pec.W")
    assert judge(zero, [0.0] * 5).verdict is Verdict.EQUIVALENT
    assert judge(zero, [0.0]).verdict is Verdict.INCONCLUSIVE  # one seed: no spread
    assert judge(zero, [math.nan] * 3).verdict is Verdict.DIFFERS  # no value


def test_halves_of_the_seeds_mark_a_claim_unstable() -> None:
    zero = next(c for c in CLAIMS if c.key == "fp.pec.W")
    stable = judge_all([{"fp.pec.W": 0.0}] * 4, {}, [zero])[0]
    assert stable.halves == (Verdict.EQUIVALENT, Verdict.EQUIVALENT)
    assert stable.unstable is False and stable.verdict_text() == "equivalent"
    # First two seeds none, last two many: the halves disagree.
    mixed = judge_all([{"fp.pec.W": v} for v in (0.0, 0.0, 5.0, 6.0, 5.5)], {}, [zero])[0]
    assert mixed.halves == (Verdict.EQUIVALENT, Verdict.DIFFERS)
    assert mixed.unstable is True and mixed.verdict_text().endswith(", unstable")
    # Fewer than two seeds per half: not measured.
    assert judge_all([{"fp.pec.W": 0.0}] * 3, {}, [zero])[0].unstable is None
    assert seed_halves(5) == (slice(0, 2), slice(3, 5))
    assert seed_halves(3) is None
