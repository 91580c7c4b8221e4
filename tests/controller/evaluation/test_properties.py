"""Properties: appending standing ticks without locks changes no count."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.evaluation.lifts import lifts_from_truth, trials_from_truth
from controller.evaluation.metrics import count_false_positives, evaluate_lifts
from controller.evaluation.study import evaluate_recording
from controller.evaluation.tables import FalsePositiveTable, PerformanceTable, lift_table
from controller.tick_record import Action

from .tick_builder import TickBuilder

KINDS = ("squat", "stoop_left", "stoop_right")
GAITS = ("walk", "turn", "stairs_up", "stairs_down")


@st.composite
def recordings(draw: st.DrawFn) -> tuple[dict[str, Any], dict[str, Any]]:
    """(recording, the same recording with standing ticks appended)."""
    pieces = draw(
        st.lists(
            st.tuples(st.sampled_from((*KINDS, *GAITS, "stand")), st.integers(1, 80)),
            min_size=1, max_size=6,
        )
    )
    n = sum(length for _, length in pieces)
    extra = draw(st.integers(1, 120))
    b = TickBuilder(n + extra)
    k, lift_index = 0, 0
    for activity, length in pieces:
        if activity in KINDS:
            b.lift(lift_index, activity, k, k + length - 1)  # type: ignore[arg-type]
            lift_index += 1
        elif activity in GAITS:
            b.gait(k, k + length - 1, activity)
        k += length
    for tick, action in draw(st.lists(st.tuples(st.integers(0, n - 1),
                                                st.sampled_from(list(Action))), max_size=8)):
        b.run(tick, action)
    for tick, kind, p in draw(st.lists(st.tuples(st.integers(0, n + extra - 1),
                                                 st.sampled_from(KINDS), st.floats(0, 1)),
                                       max_size=12)):
        b.posterior(tick, kind, p)
    for tick, tl, tr in draw(st.lists(st.tuples(st.integers(0, n - 1), st.floats(0, 40),
                                                st.floats(0, 40)), max_size=5)):
        b.torque(tick, tl, tr)
    # The appended ticks: standing, the controller idling without locks.
    tail = slice(n, n + extra)
    b.cols["lock_left"][tail] = False
    b.cols["lock_right"][tail] = False
    b.cols["action"][tail] = int(Action.NO_LOCK)
    b.cols["controller_ran"][tail] = draw(st.lists(st.booleans(), min_size=extra,
                                                   max_size=extra))
    full = b.columns()
    head = {name: col[:n] for name, col in full.items()}
    return head, full


def summary(cols: dict[str, Any]) -> tuple[str, str, str, list[Any]]:
    lifts = lifts_from_truth(cols)
    trials = trials_from_truth(cols, min_duration_s=0.0)
    ev = evaluate_recording(cols, "1", "umc", lifts, trials)
    fps = [(f.trial, f.signals, f.edges_left, f.edges_right, f.decisions, f.lock_ticks)
           for f in count_false_positives(cols, trials)]
    return (
        PerformanceTable.from_evaluations([ev]).to_csv(),
        FalsePositiveTable.from_evaluations([ev]).to_csv(),
        lift_table([ev]).to_csv(),
        fps,
    )


@settings(max_examples=60, deadline=None)
@given(recordings())
def test_counts_are_invariant_to_appended_standing_ticks(
    pair: tuple[dict[str, Any], dict[str, Any]],
) -> None:
    head, full = pair
    assert summary(head) == summary(full)


@settings(max_examples=30, deadline=None)
@given(recordings())
def test_every_lift_has_exactly_one_outcome(pair: tuple[dict[str, Any], dict[str, Any]]) -> None:
    cols = pair[1]
    lifts = lifts_from_truth(cols)
    outs = evaluate_lifts(cols, lifts)
    assert [o.lift for o in outs] == lifts
    for o in outs:
        held = np.asarray(cols["lock_left"])[o.lift.ticks] | np.asarray(cols["lock_right"])[
            o.lift.ticks]
        assert np.isnan(o.first_lock_s) == (not held.any())
        if o.first_action is not None:
            assert o.first_decision_s <= (o.lift.first_half_end - o.lift.start) * 0.01 + 1e-9
