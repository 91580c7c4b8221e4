"""A trial's ground truth from its ticks: which source wins, and the lift renumbering."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from controller.evaluation.columns import TickData
from controller.evaluation.ground_truth import ground_truth, renumbered


def _sim(lift: list[int], activity: str = "squat") -> TickData:
    n = len(lift)
    return TickData({"t": np.arange(n) * 0.01, "truth_lift": np.array(lift),
                     "truth_activity": np.array([activity if x >= 0 else "stand"
                                                 for x in lift])})


def test_a_looped_script_numbers_each_run_of_ticks_anew() -> None:
    cols = renumbered(_sim([-1, 0, 0, -1, 0, 0, 1, 1, -1]))
    assert cols.int_("truth_lift").tolist() == [-1, 0, 0, -1, 1, 1, 2, 2, -1]


@given(st.lists(st.integers(-1, 3), min_size=1, max_size=60))
def test_renumbering_keeps_every_run_and_counts_up(lift: list[int]) -> None:
    new = renumbered(_sim(lift)).int_("truth_lift")
    old = np.array(lift)
    assert ((new < 0) == (old < 0)).all()
    runs = [int(v) for i, v in enumerate(new) if v >= 0 and (i == 0 or new[i - 1] != v)]
    assert runs == list(range(len(runs)))


def test_the_simulation_wins_and_lifts_cut_by_the_trial_edges_are_left_out() -> None:
    truth = ground_truth(_sim([0, 0, -1, 1, 1, -1, 2, 2]), "lifting", [(0, 7, "squat")])
    assert truth.source == "simulation"
    assert [(lf.start, lf.end) for lf in truth.lifts] == [(3, 4)]
    assert truth.incomplete_lifts == 2


def test_without_truth_segments_then_the_task_decide() -> None:
    plain = TickData({"t": np.arange(50) * 0.01})
    seg = ground_truth(plain, "stairs", [(10, 20, "squat")])
    assert (seg.source, len(seg.lifts), [g.kind for g in seg.gait]) == (
        "segments", 1, ["stair_walking"])
    waiting = ground_truth(plain, "lifting", [(10, 20, "unlabelled")])
    assert waiting.source == "none" and "cannot be used yet" in waiting.note
    walk = ground_truth(plain, "Walking", ())
    assert walk.source == "task" and (walk.gait[0].start, walk.gait[0].end) == (0, 49)
    assert ground_truth(plain, "lifting").source == "none"
    assert ground_truth(TickData({}), "walking").note == "the trial has no stored ticks"
