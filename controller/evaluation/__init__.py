"""Evaluation of recorded controller output: the paper's metrics, tables and figures.

A pure analysis package (NumPy, SciPy, Matplotlib on an offscreen Agg canvas; nothing
from the backend), so that the backend, the CLI and a virtual study compute the
evaluation the same way. The flow:

1. Tick data as columns (`TickData`, field names of `controller.tick_record.TickRecord`).
2. Ground truth: `lifts_from_truth` / `trials_from_truth` for a simulated recording,
   `lifts_from_segments` / `whole_recording_trial` for an experimenter's segments.
3. `evaluate_recording` per recording, labelled with participant and controller.
4. Tables (`PerformanceTable`, `FalsePositiveTable`, `QuestionnaireTable`,
   `lift_table`, `onset_to_lock_table`) and figures (`peak_torque_figure`,
   `controller_output_figure`, `onset_to_lock_figure`, rendered by `render_figure`).

The metric definitions are in `controller.evaluation.metrics`.
"""

from controller.evaluation.columns import Columns, TickData
from controller.evaluation.figures import onset_to_lock_figure, peak_torque_figure
from controller.evaluation.lifts import (
    CORRECT_ACTION,
    LIFT_KINDS,
    TRIAL_KINDS,
    GaitTrial,
    Lift,
    LiftKind,
    TrialKind,
    lift_kind,
    lifts_from_segments,
    lifts_from_truth,
    trial_kind,
    trials_from_truth,
    whole_recording_trial,
)
from controller.evaluation.metrics import (
    RECOGNITION_THRESHOLD,
    DecisionOutcome,
    FalsePositives,
    LiftOutcome,
    OnsetToLockSummary,
    count_false_positives,
    estimates_intent,
    evaluate_lift,
    evaluate_lifts,
    lock_decisions,
    onset_to_lock_times,
    summarise_onset_to_lock,
)
from controller.evaluation.rendering import RenderedFigure, render_figure
from controller.evaluation.study import (
    RecordingEvaluation,
    controller_label,
    evaluate_recording,
)
from controller.evaluation.tables import (
    FalsePositiveRow,
    FalsePositiveTable,
    PerformanceRow,
    PerformanceTable,
    QuestionnaireScore,
    QuestionnaireTable,
    Table,
    lift_table,
    onset_to_lock_table,
)
from controller.evaluation.timeline import ModelSetLike, controller_output_figure
from controller.evaluation.torques import recompute_torques

__all__ = [
    "CORRECT_ACTION",
    "LIFT_KINDS",
    "RECOGNITION_THRESHOLD",
    "TRIAL_KINDS",
    "Columns",
    "DecisionOutcome",
    "FalsePositiveRow",
    "FalsePositiveTable",
    "FalsePositives",
    "GaitTrial",
    "Lift",
    "LiftKind",
    "LiftOutcome",
    "ModelSetLike",
    "OnsetToLockSummary",
    "PerformanceRow",
    "PerformanceTable",
    "QuestionnaireScore",
    "QuestionnaireTable",
    "RecordingEvaluation",
    "RenderedFigure",
    "Table",
    "TickData",
    "TrialKind",
    "controller_label",
    "controller_output_figure",
    "count_false_positives",
    "estimates_intent",
    "evaluate_lift",
    "evaluate_lifts",
    "evaluate_recording",
    "lift_kind",
    "lift_table",
    "lifts_from_segments",
    "lifts_from_truth",
    "lock_decisions",
    "onset_to_lock_figure",
    "onset_to_lock_table",
    "onset_to_lock_times",
    "peak_torque_figure",
    "recompute_torques",
    "render_figure",
    "summarise_onset_to_lock",
    "trial_kind",
    "trials_from_truth",
    "whole_recording_trial",
]
