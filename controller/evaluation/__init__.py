"""Evaluation of recorded controller output: the paper's metrics, tables and figures.

A pure analysis package (NumPy, SciPy, Matplotlib on an offscreen Agg canvas; nothing
from the backend), so that the backend, the CLI and a virtual study compute the
evaluation the same way. The flow, each step in its own module (import from the module;
this package re-exports nothing, so that a caller pays only for the steps it uses):

1. Tick data as columns (`columns.TickData`, field names of
   `controller.tick_record.TickRecord`).
2. Ground truth (`ground_truth`); the lifts and gait trials (`lifts`):
   `lifts_from_truth` / `trials_from_truth` for a simulated recording,
   `lifts_from_segments` / `whole_recording_trial` for an experimenter's segments.
3. `study.evaluate_recording` per recording, labelled with participant and controller;
   the metric definitions are in `metrics`, recomputed torques in `torques`.
4. Tables (`tables`: `PerformanceTable`, `FalsePositiveTable`, `QuestionnaireTable`,
   `lift_table`, `onset_to_lock_table`) and figures (`figures.peak_torque_figure`,
   `figures.onset_to_lock_figure`, `timeline.controller_output_figure`), rendered by
   `rendering.render_figure`.
"""
