"""The one automatic segmentation behind recordings and trials: the lifts the
controller's segmentation finds, labelled from the ticks' truth where it names a motion."""

from __future__ import annotations

import numpy as np
import pytest

from backend.analysis.segmentation import SegmentationError, propose_lifts
from controller.intent.segmentation import segment_lifts

RATE = 100


def _two_lifts() -> dict[str, np.ndarray]:
    """Rest, a lift to 1.4 rad (3 s), rest, a second lift, rest: both hips alike."""
    rest = np.zeros(3 * RATE)
    lift = 1.4 * np.sin(np.linspace(0.0, np.pi, 3 * RATE)) ** 2
    m = np.concatenate([rest, lift, rest, lift, rest])
    truth = np.array([""] * m.size, dtype=object)
    truth[3 * RATE:6 * RATE] = "squat"
    truth[9 * RATE:12 * RATE] = "walking"  # not a motion model: unlabelled
    return {"q_left": m.copy(), "q_right": m.copy(), "truth_activity": truth}


def test_lifts_match_the_segmentation_and_take_the_truth_at_their_peak() -> None:
    cols = _two_lifts()
    q = np.column_stack([cols["q_left"], cols["q_right"]])
    expected = segment_lifts(np.arange(q.shape[0]) / RATE, q)
    found = propose_lifts(cols)
    assert [(p.start, p.peak, p.end) for p in found] == [
        (s.start, s.peak, s.end) for s in expected]
    assert len(found) == 2
    assert [p.label for p in found] == ["squat", "unlabelled"]
    assert 3 * RATE <= found[0].peak < 6 * RATE


def test_bad_samples_are_bridged_before_segmenting() -> None:
    cols = _two_lifts()
    clean = propose_lifts(cols)
    cols["q_left"][50:60] = np.nan  # a short dropout while standing
    assert propose_lifts(cols) == clean


@pytest.mark.parametrize(("n", "fill", "reason"), [
    (99, 0.0, "too_short"), (400, np.nan, "no_angles")])
def test_what_cannot_be_segmented_is_named(n: int, fill: float, reason: str) -> None:
    cols = {"q_left": np.full(n, fill), "q_right": np.full(n, fill),
            "truth_activity": np.array([""] * n, dtype=object)}
    with pytest.raises(SegmentationError) as err:
        propose_lifts(cols)
    assert (err.value.reason, err.value.samples) == (reason, n)
