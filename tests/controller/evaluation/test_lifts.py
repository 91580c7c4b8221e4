"""Ground truth: tick columns, lifts from the simulation's truth and from segments, trials."""

from __future__ import annotations

import numpy as np
import pytest

from controller.evaluation.columns import TickData
from controller.evaluation.lifts import (
    GaitTrial,
    Lift,
    lift_kind,
    lifts_from_segments,
    lifts_from_truth,
    trial_kind,
    trials_from_truth,
    whole_recording_trial,
)
from controller.sim.recording import simulate_angles
from controller.tick_codec import columns_from_records

from .tick_builder import TickBuilder, simulate_pec


def segments_from_trajectory(script: str, seed: int) -> list[tuple[int, int, str]]:
    """What an experimenter would have marked: every lift of the simulated trajectory
    (not of the ticks) as start, end and label, in shuffled order."""
    truth = simulate_angles(seed, script).truth
    segs = []
    for idx in np.unique(truth.lift_index[truth.lift_index >= 0]):
        where = np.flatnonzero(truth.lift_index == idx)
        label = str(truth.activity[where[0]]).replace("_", " ").title()  # "Stoop Left"
        segs.append((int(where[0]), int(where[-1]), label))
    return segs[::-1]


def test_truth_from_columns_equals_truth_from_segments_on_a_simulated_recording() -> None:
    records = simulate_pec("stoop-sequence", seed=5)
    cols = TickData.from_records(records)
    from_truth = lifts_from_truth(cols)
    from_segments = lifts_from_segments(segments_from_trajectory("stoop-sequence", 5), len(cols))
    assert from_truth == from_segments
    assert [lf.kind for lf in from_truth].count("stoop_left") == 5
    assert [lf.kind for lf in from_truth].count("stoop_right") == 5
    assert [lf.index for lf in from_truth] == list(range(10))
    # The replay's plain column dict (strings as objects) gives the same lifts.
    assert lifts_from_truth(columns_from_records(records)) == from_truth


def test_gait_trials_of_the_simulated_protocol() -> None:
    sim = simulate_angles(3, "paper-evaluation")
    cols = {"t": sim.t, "truth_activity": sim.truth.activity, "truth_lift": sim.truth.lift_index}
    trials = trials_from_truth(cols)
    assert [tr.kind for tr in trials] == ["walking", "stair_walking"]
    walk = sim.truth.activity[trials[0].ticks]
    assert set(walk.tolist()) == {"walk", "turn"}
    assert {"stairs_up", "stairs_down"} <= set(sim.truth.activity[trials[1].ticks].tolist())
    assert len(lifts_from_truth(cols)) == 20


def test_labels() -> None:
    assert lift_kind("SQ") == "squat"
    assert lift_kind(" stoop-left ") == "stoop_left"
    assert lift_kind("Stoop Right") == "stoop_right"
    assert trial_kind("stairs") == "stair_walking"
    assert trial_kind("W") == "walking"
    with pytest.raises(ValueError, match="unknown lift"):
        lift_kind("walk")
    with pytest.raises(ValueError, match="unknown trial"):
        trial_kind("squat-sequence")


def test_segments_validation() -> None:
    assert lifts_from_segments([(30, 40, "squat"), (0, 10, "sq")]) == [
        Lift(0, "squat", 0, 10), Lift(1, "squat", 30, 40)
    ]
    assert lifts_from_segments([(0, 10, "other"), (20, 30, "SL")]) == [
        Lift(0, "stoop_left", 20, 30)
    ]
    with pytest.raises(ValueError, match="unknown lift"):
        lifts_from_segments([(0, 10, "unlabelled")])
    with pytest.raises(ValueError, match="overlap"):
        lifts_from_segments([(0, 10, "squat"), (10, 20, "squat")])
    with pytest.raises(ValueError, match="beyond"):
        lifts_from_segments([(0, 10, "squat")], n_ticks=10)
    with pytest.raises(ValueError, match="start <= end"):
        lifts_from_segments([(10, 5, "squat")])


def test_truth_validation() -> None:
    b = TickBuilder(100)
    b.lift(0, "squat", 10, 20)
    b.cols["truth_lift"][30:35] = 0  # the same index again later
    with pytest.raises(ValueError, match="contiguous"):
        lifts_from_truth(b.columns())
    b = TickBuilder(100)
    b.lift(0, "squat", 10, 20)
    b.cols["truth_activity"][15] = "stoop_left"
    with pytest.raises(ValueError, match="activities"):
        lifts_from_truth(b.columns())


def test_whole_recording_trial() -> None:
    assert whole_recording_trial(500, "walking") == GaitTrial("walking", 0, 499)
    assert whole_recording_trial({"t": np.zeros(7)}, "SW") == GaitTrial("stair_walking", 0, 6)
    with pytest.raises(ValueError):
        whole_recording_trial(0, "walking")


def test_columns_read_what_storage_gives() -> None:
    cols = TickData(
        {
            "t": [0.0, None, 0.02, 0.03],
            "lock_left": ["true", "0", "1", "False"],
            "action": [1.0, 2.0, 2.0, 1.0],
            "truth_activity": np.array(["stand", None, "squat", "squat"], dtype=object),
            "post_squat": ["", "0.25", "", "1"],
            "id": [9, 9, 9, 9],  # not a tick field: ignored
        }
    )
    assert cols.names == ("t", "lock_left", "action", "truth_activity", "post_squat")
    assert cols.bool_("lock_left").tolist() == [True, False, True, False]
    assert cols.int_("action").tolist() == [1, 2, 2, 1]
    assert cols.str_("truth_activity").tolist() == ["stand", "", "squat", "squat"]
    assert np.isnan(cols.float_("post_squat")[[0, 2]]).all()
    assert cols.time() == pytest.approx([0.0, 0.01, 0.02, 0.03])
    assert len(cols.select(1, 3)) == 2
    with pytest.raises(ValueError, match="has 2 values"):
        TickData({"t": [0.0, 1.0, 2.0], "action": [1, 1]})
    with pytest.raises(ValueError, match="not provided"):
        cols.float_("q_left")
    with pytest.raises(ValueError, match="not a TickRecord field"):
        cols.float_("q_middle")
    with pytest.raises(ValueError, match="fractions"):
        TickData({"action": [1.5]})
    mine = np.zeros(3)
    TickData({"t": mine})
    mine[0] = 1.0  # checking the columns does not freeze the caller's arrays
    assert TickData({}).time().size == 0
    assert TickData({"action": [1, 1]}).time() == pytest.approx([0.0, 0.01])
