"""The paper's metrics on hand-made tick sequences whose answers are known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.evaluation.lifts import GaitTrial, Lift, lifts_from_truth, trials_from_truth
from controller.evaluation.metrics import (
    DecisionOutcome,
    count_false_positives,
    evaluate_lift,
    evaluate_lifts,
    lock_decisions,
    summarise_onset_to_lock,
)
from controller.evaluation.study import evaluate_recording
from controller.tick_record import Action

from .tick_builder import TickBuilder


def one_lift(kind: str = "squat", start: int = 100, end: int = 199) -> tuple[TickBuilder, Lift]:
    b = TickBuilder(300)
    lift = b.lift(0, kind, start, end)  # type: ignore[arg-type]
    return b, lift


def test_first_half_is_start_plus_half_the_duration() -> None:
    assert Lift(0, "squat", 100, 199).first_half_end == 149  # 100 ticks: 100..149
    assert Lift(0, "squat", 100, 200).first_half_end == 150  # odd: the middle tick included
    assert Lift(0, "squat", 7, 7).first_half_end == 7


def test_correct_first_decision() -> None:
    b, lift = one_lift("stoop_left")
    b.run(120, Action.LOCK_LEFT)
    b.run(130, Action.LOCK_BOTH)  # locking both later in a stoop is fine (paper)
    o = evaluate_lift(b.columns(), lift)
    assert o.decision is DecisionOutcome.CORRECT
    assert o.first_action is Action.LOCK_LEFT
    assert o.first_decision_s == pytest.approx(0.20)


def test_squat_locked_left_then_both_counts_as_correct_but_not_first_decision() -> None:
    # The paper counts a squat as correct once both sides are locked in the first half,
    # in one decision or two; the stricter first-decision reading calls it wrong.
    b, lift = one_lift("squat")
    b.run(115, Action.LOCK_LEFT)
    b.run(125, Action.LOCK_BOTH)
    o = evaluate_lift(b.columns(), lift)
    assert o.decision is DecisionOutcome.CORRECT
    assert o.first_decision is DecisionOutcome.WRONG
    assert o.first_lock_one_sided is True and o.sides_commanded == "LR"
    assert o.first_action is Action.LOCK_LEFT
    # The correct side(s) -- both, for a squat -- are held once the right side follows.
    assert o.first_lock_s == pytest.approx(0.15)
    assert o.correct_lock_s == pytest.approx(0.25)


def test_squat_locked_right_then_left_in_two_decisions_is_correct() -> None:
    b, lift = one_lift("squat")
    b.run(110, Action.LOCK_RIGHT)
    b.run(149, Action.LOCK_LEFT)  # the last tick of the first half
    o = evaluate_lift(b.columns(), lift)
    assert (o.decision, o.first_decision) == (DecisionOutcome.CORRECT, DecisionOutcome.WRONG)
    assert o.sides_commanded == "LR"


def test_squat_with_the_second_side_only_after_the_first_half_is_wrong() -> None:
    b, lift = one_lift("squat")
    b.run(110, Action.LOCK_RIGHT)
    b.run(150, Action.LOCK_LEFT)  # first tick of the second half: too late
    o = evaluate_lift(b.columns(), lift)
    assert (o.decision, o.first_decision) == (DecisionOutcome.WRONG, DecisionOutcome.WRONG)
    assert o.sides_commanded == "R" and o.first_lock_one_sided is True


def test_squat_locked_both_at_once_is_correct_under_both_readings() -> None:
    b, lift = one_lift("squat")
    b.run(120, Action.LOCK_BOTH)
    o = evaluate_lift(b.columns(), lift)
    assert (o.decision, o.first_decision) == (DecisionOutcome.CORRECT, DecisionOutcome.CORRECT)
    assert o.first_lock_one_sided is False and o.sides_commanded == "LR"


@pytest.mark.parametrize(
    ("kind", "decisions", "paper", "first"),
    [
        # stoop: only the first lock decision counts, and it must be the supporting side
        ("stoop_left", [Action.LOCK_BOTH, Action.LOCK_LEFT], "wrong", "wrong"),
        ("stoop_left", [Action.LOCK_RIGHT, Action.LOCK_LEFT], "wrong", "wrong"),
        ("stoop_right", [Action.LOCK_RIGHT, Action.LOCK_BOTH], "correct", "correct"),
        ("stoop_right", [Action.LOCK_LEFT], "wrong", "wrong"),
        ("squat", [Action.LOCK_LEFT], "wrong", "wrong"),
        ("squat", [Action.LOCK_LEFT, Action.LOCK_RIGHT], "correct", "wrong"),
        ("squat", [Action.LOCK_RIGHT, Action.LOCK_RIGHT], "wrong", "wrong"),
        ("squat", [Action.LOCK_BOTH, Action.LOCK_LEFT], "correct", "correct"),
    ],
)
def test_counting_rules_on_hand_built_lifts(
    kind: str, decisions: list[Action], paper: str, first: str
) -> None:
    b, lift = one_lift(kind)
    for i, a in enumerate(decisions):
        b.run(105 + 10 * i, a)
    o = evaluate_lift(b.columns(), lift)
    assert (o.decision.value, o.first_decision.value) == (paper, first)


def test_late_lock_after_the_first_half_is_missed() -> None:
    b, lift = one_lift("squat")
    b.run(150, Action.LOCK_BOTH)  # first tick of the second half
    o = evaluate_lift(b.columns(), lift)
    assert o.decision is DecisionOutcome.MISSED
    assert o.first_decision is DecisionOutcome.MISSED and o.sides_commanded == ""
    assert o.first_action is None and math.isnan(o.first_decision_s)
    assert o.first_lock_s == pytest.approx(0.50)  # it did lock, late


def test_lock_decided_on_the_last_tick_of_the_first_half_counts() -> None:
    b, lift = one_lift("stoop_right")
    b.run(149, Action.LOCK_RIGHT)
    assert evaluate_lift(b.columns(), lift).decision is DecisionOutcome.CORRECT


def test_held_action_between_runs_is_not_a_new_decision() -> None:
    # A lock decided before the lift keeps `action` at 2 on the following ticks, but
    # those ticks are no decisions: the controller did not run.
    b, lift = one_lift("stoop_left")
    b.run(50, Action.LOCK_BOTH)
    b.run(140, Action.LOCK_LEFT)
    cols = b.columns()
    assert cols["action"][120] == int(Action.LOCK_BOTH)
    assert lock_decisions(cols).sum() == 2
    assert evaluate_lift(cols, lift).decision is DecisionOutcome.CORRECT


def test_no_lock_runs_are_not_lock_decisions() -> None:
    b, lift = one_lift("squat")
    for k in range(100, 200):
        b.run(k, Action.NO_LOCK)  # an idle E-UMC decides "no lock" at 100 Hz
    o = evaluate_lift(b.columns(), lift)
    assert o.decision is DecisionOutcome.MISSED
    assert math.isnan(o.first_lock_s) and math.isnan(o.correct_lock_s)


def test_posterior_reaching_half_only_in_the_second_half_is_not_recognised() -> None:
    b, lift = one_lift("stoop_right")
    for k in range(100, 150, 10):
        b.posterior(k, "stoop_right", 0.49)
    b.posterior(150, "stoop_right", 0.9)
    o = evaluate_lift(b.columns(), lift)
    assert o.recognised is False
    assert o.peak_posterior == pytest.approx(0.49)
    assert math.isnan(o.recognised_s)


def test_posterior_of_exactly_half_in_the_first_half_is_recognised() -> None:
    b, lift = one_lift("squat")
    b.posterior(130, "squat", 0.5)
    o = evaluate_lift(b.columns(), lift)
    assert o.recognised is True
    assert o.recognised_s == pytest.approx(0.30)


def test_only_the_correct_models_posterior_counts() -> None:
    b, lift = one_lift("stoop_left")
    b.posterior(120, "stoop_right", 0.95)
    assert evaluate_lift(b.columns(), lift).recognised is False


def test_no_posteriors_at_all_means_no_recognition_rather_than_false() -> None:
    b, lift = one_lift("squat")
    b.run(120, Action.LOCK_BOTH)  # a PEC: decisions, no intent estimation
    o = evaluate_lift(b.columns(), lift)
    assert o.recognised is None and math.isnan(o.peak_posterior)
    assert o.decision is DecisionOutcome.CORRECT
    # Told explicitly that the controller estimates intent, the same lift is a miss.
    assert evaluate_lift(b.columns(), lift, with_intent=True).recognised is False


def test_peak_torques_over_the_whole_lift() -> None:
    b, lift = one_lift("stoop_left")
    b.torque(120, 5.0, 1.0)
    b.torque(180, 12.5, 2.0)  # second half still counts: the peak of the lift
    b.torque(250, 40.0, 40.0)  # after the lift
    b.cols["torque_left"][190] = np.nan
    o = evaluate_lift(b.columns(), lift)
    assert (o.peak_torque_left, o.peak_torque_right) == (12.5, 2.0)


def test_missing_torque_columns_give_nan_peaks() -> None:
    b, lift = one_lift()
    cols = b.columns()
    del cols["torque_left"], cols["torque_right"]
    o = evaluate_lift(cols, lift)
    assert math.isnan(o.peak_torque_left) and math.isnan(o.peak_torque_right)


def test_missing_decision_columns_are_named() -> None:
    b, lift = one_lift()
    cols = b.columns()
    del cols["controller_ran"]
    with pytest.raises(ValueError, match="controller_ran"):
        evaluate_lift(cols, lift)


def test_lift_beyond_the_recording_is_rejected() -> None:
    b, _ = one_lift()
    with pytest.raises(ValueError, match="beyond"):
        evaluate_lift(b.columns(), Lift(3, "squat", 250, 400))


def test_lock_during_a_walking_trial_is_a_false_positive() -> None:
    b = TickBuilder(1200)
    b.gait(100, 999, "walk")
    b.run(80, Action.LOCK_BOTH)  # before the trial, held 10 ticks into it: no new signal
    b.run(300, Action.LOCK_RIGHT)
    b.run(310, Action.LOCK_RIGHT)  # 0.1 s later, within the hold: the same signal
    b.run(600, Action.LOCK_LEFT)
    b.run(610, Action.LOCK_BOTH)  # adds the right side to a held left: one signal, 2 edges
    b.run(1100, Action.LOCK_BOTH)  # after the trial
    cols = b.columns()
    trials = trials_from_truth(cols)
    assert trials == [GaitTrial("walking", 100, 999)]
    (fp,) = count_false_positives(cols, trials)
    assert fp.signals == 2
    assert (fp.edges_left, fp.edges_right) == (1, 2)
    assert fp.decisions == 4
    assert fp.lock_ticks == 10 + 40 + 40
    assert fp.duration_s == pytest.approx(8.99)


def test_stairs_make_a_stair_walking_trial_and_short_walks_are_no_trial() -> None:
    b = TickBuilder(2000)
    b.gait(10, 160, "walk")  # 1.5 s between stations
    b.gait(300, 599, "walk")
    b.gait(600, 1199, "stairs_up")
    b.gait(1200, 1499, "turn")
    b.run(700, Action.LOCK_LEFT)
    cols = b.columns()
    trials = trials_from_truth(cols)
    assert trials == [GaitTrial("stair_walking", 300, 1499)]
    assert count_false_positives(cols, trials)[0].signals == 1
    assert trials_from_truth(cols, min_duration_s=1.0)[0] == GaitTrial("walking", 10, 160)


def test_no_locks_no_false_positives() -> None:
    b = TickBuilder(800)
    b.gait(0, 799, "stairs_down")
    for k in range(0, 800, 10):
        b.run(k, Action.NO_LOCK)
    (fp,) = count_false_positives(b.columns(), trials_from_truth(b.columns()))
    assert (fp.signals, fp.decisions, fp.lock_ticks) == (0, 0, 0)


def test_command_held_at_the_first_tick_is_a_rising_edge() -> None:
    b = TickBuilder(100)
    b.run(0, Action.LOCK_LEFT)
    (fp,) = count_false_positives(b.columns(), [GaitTrial("walking", 0, 99)])
    assert fp.signals == 1


def test_onset_to_lock_summary() -> None:
    b = TickBuilder(1000)
    lifts = [b.lift(i, "squat", 100 + 200 * i, 199 + 200 * i) for i in range(4)]
    for i, delay in enumerate((10, 20, 40)):  # the fourth lift never locks
        b.run(lifts[i].start + delay, Action.LOCK_BOTH)
    outs = evaluate_lifts(b.columns(), lifts_from_truth(b.columns()))
    s = summarise_onset_to_lock(outs, "first")
    assert (s.n_lifts, s.n_locked) == (4, 3)
    assert s.median_s == pytest.approx(0.20)
    assert (s.q25_s, s.q75_s) == (pytest.approx(0.15), pytest.approx(0.30))
    assert s.iqr_s == pytest.approx(0.15)
    empty = summarise_onset_to_lock(outs[3:], "correct")
    assert empty.n_locked == 0 and math.isnan(empty.median_s)
    with pytest.raises(ValueError):
        summarise_onset_to_lock(outs, "best")  # type: ignore[arg-type]


def test_times_use_the_device_clock_across_a_nan_timestamp() -> None:
    b, lift = one_lift("squat")
    b.cols["t"] = b.cols["t"] * 2.0  # 50 Hz device clock
    b.cols["t"][110] = np.nan  # a bad sample
    b.run(120, Action.LOCK_BOTH)
    assert evaluate_lift(b.columns(), lift).first_decision_s == pytest.approx(0.40)


def test_intent_estimation_is_known_by_controller_name() -> None:
    b, lift = one_lift("squat")  # no posterior anywhere: the trigger never fired
    cols = b.columns()
    assert evaluate_recording(cols, "1", "eumc", [lift]).lifts[0].recognised is False
    assert evaluate_recording(cols, "1", "PEC", [lift]).lifts[0].recognised is None
    assert evaluate_recording(cols, "1", "mine", [lift]).lifts[0].recognised is None
    b.posterior(20, "squat", 0.9)  # before the lift: the data show intent estimation
    assert evaluate_recording(b.columns(), "1", "mine", [lift]).lifts[0].recognised is False
    forced = evaluate_recording(b.columns(), "1", "umc", [lift], with_intent=False)
    assert forced.lifts[0].recognised is None


_LOCKS = [Action.LOCK_BOTH, Action.LOCK_LEFT, Action.LOCK_RIGHT]


@given(
    kind=st.sampled_from(["squat", "stoop_left", "stoop_right"]),
    plan=st.lists(st.tuples(st.integers(100, 199), st.sampled_from(_LOCKS)), max_size=5,
                  unique_by=lambda x: x[0]),
)
@settings(max_examples=80, deadline=None)
def test_paper_rule_against_an_independent_oracle(
    kind: str, plan: list[tuple[int, Action]]
) -> None:
    """Random decisions in a lift of ticks 100..199 (first half 100..149), checked
    against the rules written out plainly."""
    b, lift = one_lift(kind)
    for k, a in sorted(plan):
        b.run(k, a)
    o = evaluate_lift(b.columns(), lift)
    early = [a for k, a in sorted(plan) if k <= 149]
    sides = set()
    for a in early:
        sides |= {"L", "R"} if a is Action.LOCK_BOTH else {"L"} if a is Action.LOCK_LEFT else {"R"}
    want = {"squat": Action.LOCK_BOTH, "stoop_left": Action.LOCK_LEFT,
            "stoop_right": Action.LOCK_RIGHT}[kind]
    first = "missed" if not early else "correct" if early[0] is want else "wrong"
    if kind == "squat":
        paper = "missed" if not sides else "correct" if sides == {"L", "R"} else "wrong"
    else:
        paper = first
    assert (o.decision.value, o.first_decision.value) == (paper, first)
    # The stricter reading never counts more correct lifts than the paper's.
    assert not (first == "correct" and paper != "correct")
