"""Ground truth of a long-use trial: gait bouts from markers, confirmed and unconfirmed
lifts from segments, and the simulation's truth when the ticks carry it."""

from __future__ import annotations

import numpy as np

from backend.analysis.wearer_progress import long_use_truth, marker_bouts
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import GaitTrial
from tests.controller.evaluation.tick_builder import TickBuilder


def test_a_gait_marker_starts_a_bout_and_the_next_marker_ends_it() -> None:
    t = np.arange(1000) * 0.01
    marks = [(2.0, "Walking"), (4.0, "box dropped"), (5.0, "stairs"), (1.0, "note")]
    assert marker_bouts(t, marks) == [GaitTrial("walking", 200, 399),
                                      GaitTrial("stair_walking", 500, 999)]
    # Back to back: walking up to the stairs; a bout of no tick is none.
    assert marker_bouts(t, [(2.0, "walk"), (3.0, "SW"), (3.0, "standing")]) == [
        GaitTrial("walking", 200, 299)]
    assert marker_bouts(t, [(20.0, "walking")]) == []
    assert marker_bouts(np.zeros(0), [(0.0, "walking")]) == []


def _real(n: int) -> TickData:
    b = TickBuilder(n)
    b.cols["truth_activity"][:] = ""
    return TickData(b.columns())


def test_real_trial_confirmed_unconfirmed_and_other_segments() -> None:
    cols = _real(1000)
    truth = long_use_truth(cols, [(100, 199, "squat"), (300, 399, "unlabelled"),
                                  (500, 599, "other"), (700, 799, "Stoop left")],
                           [(8.5, "stairs")])
    assert truth.source == "segments"
    assert [(lf.kind, lf.start, lf.end) for lf in truth.lifts] == [
        ("squat", 100, 199), ("stoop_left", 700, 799)]
    assert truth.unconfirmed == 1 and truth.incomplete == 0
    assert truth.gait == (GaitTrial("stair_walking", 850, 999),)


def test_unusable_segments_and_no_truth_at_all_say_so() -> None:
    cols = _real(1000)
    bad = long_use_truth(cols, [(100, 300, "squat"), (200, 400, "squat")], [])
    assert bad.source == "none" and "overlap" in bad.note and bad.lifts == ()
    assert long_use_truth(cols, [], []).source == "none"
    assert long_use_truth(TickData({}), [], []).source == "none"


def test_simulated_truth_wins_and_counts_cut_lifts_as_incomplete() -> None:
    b = TickBuilder(1000)
    b.lift(0, "squat", 0, 99)        # under way at the first tick: cut
    b.lift(1, "stoop_right", 300, 399)
    b.gait(400, 999)                  # 6 s of walking: a bout (5 s at least)
    truth = long_use_truth(TickData(b.columns()), [(300, 399, "unlabelled")], [])
    assert truth.source == "simulation"
    assert [lf.kind for lf in truth.lifts] == ["stoop_right"]
    assert truth.incomplete == 1 and truth.unconfirmed == 0
    assert truth.gait == (GaitTrial("walking", 400, 999),)
