"""End to end on real controller output: the PEC on the simulated wearer.

The PEC needs no models, so this does not depend on model fitting or utilities.
"""

from __future__ import annotations

import numpy as np

from controller.evaluation.columns import TickData
from controller.evaluation.figures import peak_torque_figure
from controller.evaluation.lifts import lifts_from_truth, trials_from_truth, whole_recording_trial
from controller.evaluation.metrics import DecisionOutcome
from controller.evaluation.rendering import render_figure
from controller.evaluation.study import evaluate_recording
from controller.evaluation.tables import FalsePositiveTable, PerformanceTable

from .tick_builder import simulate_pec


def test_pec_locks_both_in_every_squat_and_never_while_walking() -> None:
    squats = TickData.from_records(simulate_pec("squat-sequence", seed=2))
    lifts = lifts_from_truth(squats)
    ev = evaluate_recording(squats, "1", "pec", lifts)
    assert len(ev.lifts) == 10
    assert all(o.decision is DecisionOutcome.CORRECT for o in ev.lifts)
    assert all(o.recognised is None for o in ev.lifts)  # no intent estimation
    left = np.array([o.peak_torque_left for o in ev.lifts])
    right = np.array([o.peak_torque_right for o in ev.lifts])
    assert (left > 5.0).all() and (right > 5.0).all()
    assert np.abs(left - right).max() < 0.25 * right.max()  # symmetric support
    assert all(0.0 < o.first_lock_s < 1.0 for o in ev.lifts)

    walk = TickData.from_records(simulate_pec("walking", seed=2))
    trials = trials_from_truth(walk)
    assert [t.kind for t in trials] == ["walking"]
    fp_ev = evaluate_recording(walk, "1", "pec", trials=[whole_recording_trial(walk, "walking")])
    assert fp_ev.false_positives[0].signals == 0

    perf = PerformanceTable.from_evaluations([ev]).to_markdown()
    assert "| Decision correct | SQ | 10 |" in perf
    fp = FalsePositiveTable.from_evaluations([fp_ev]).to_markdown()
    assert "| PEC | W | 0 |" in fp
    assert "| PEC | SW | / |" in fp
    assert render_figure(peak_torque_figure([ev])).width_px == 400
