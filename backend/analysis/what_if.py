"""The what-if replay: a stored trial's raw hip angles through another configuration,
both runs scored against the same ground truth. Nothing is written."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from sqlalchemy import Engine
from sqlalchemy.orm import Session

from backend.analysis.results import (
    ResultsError,
    set_document,
    trial_columns,
    trial_segments,
)
from backend.db.evidence_tables import ModelSetRecord, Trial, UtilitySetRecord
from backend.schemas.results import WhatIfOut
from controller.config import ControllerConfig, SettingError
from controller.controllers import registry
from controller.controllers.factory import make_from_spec, needs_models
from controller.controllers.spec import ControllerSpec
from controller.evaluation.columns import TickData
from controller.evaluation.ground_truth import ground_truth, has_truth
from controller.evaluation.lifts import GaitTrial
from controller.evaluation.metrics import (
    DecisionOutcome,
    LiftOutcome,
    count_false_positives,
    evaluate_lifts,
    summarise_onset_to_lock,
)
from controller.evaluation.study import controller_label


def summary(outcomes: Sequence[LiftOutcome], cols: TickData, gait: Sequence[GaitTrial],
            controller: str) -> dict[str, Any]:
    """Headline numbers of one run: recognitions, decisions, false positives, locks."""
    rec = [o.recognised for o in outcomes]
    dec = [o.decision for o in outcomes]
    fps = count_false_positives(cols, gait) if len(cols) else []
    onset = summarise_onset_to_lock(outcomes, "first")

    def num(x: float) -> float | None:
        return None if math.isnan(x) else round(float(x), 4)

    return {
        "controller": controller,
        "lifts": len(outcomes),
        "recognised": None if outcomes and all(r is None for r in rec) else sum(
            1 for r in rec if r),
        "decision_correct": dec.count(DecisionOutcome.CORRECT),
        "decision_wrong": dec.count(DecisionOutcome.WRONG),
        "decision_missed": dec.count(DecisionOutcome.MISSED),
        "false_positive_signals": sum(f.signals for f in fps),
        "gait_trials": len(fps),
        "lock_ticks": int(np.count_nonzero(cols.bool_("lock_left") | cols.bool_("lock_right")))
        if len(cols) else 0,
        "onset_to_lock_median_s": num(onset.median_s),
        "ticks": len(cols),
    }


def what_if(engine: Engine, db: Session, trial: Trial, controller: str,
            model_set_id: int | None = None, utility_set_id: int | None = None,
            rate_hz: float | None = None,
            settings: Mapping[str, Any] | None = None) -> WhatIfOut:
    """Replay the trial's stored raw hip angles through another configuration.

    The stored angles (`q_raw_left/right`, device time `t`) go through
    `controller.runner.replay.replay_columns`, the live tick code with the mechanism simulated
    in between. The configuration starts from the settings the trial ran with (its
    snapshot, calibration included), then `settings` overrides single fields and
    `rate_hz` sets every controller's rate. Nothing is written: the original ticks and
    trial row are only read. Both runs are scored against the same ground truth.
    """
    # The batch replay on first use: it imports the simulated mechanism, whose compiled
    # kernels would otherwise load at every server start.
    from controller.runner.replay import AngleRecording, replay_columns

    cols = trial_columns(engine, trial)
    if len(cols) == 0:
        raise ResultsError("status", f"trial {trial.id} has no stored ticks")
    snap = dict((trial.config_snapshot or {}).get("settings") or {})
    try:
        base = ControllerConfig.from_json(snap) if snap else ControllerConfig()
        merged = base.to_json() | dict(settings or {})
        config = ControllerConfig.from_json(merged)
    except SettingError as exc:
        raise ResultsError(f"settings.{exc.field}", exc.problem) from exc
    except (TypeError, ValueError) as exc:
        raise ResultsError("settings", str(exc)) from exc
    if rate_hz is not None:
        try:
            config = config.at_rate(rate_hz)
        except SettingError as exc:
            raise ResultsError("rate_hz", exc.problem) from exc
    sets = needs_models(controller)
    if registry.needs_calibration(controller) and config.calibration is None:
        raise ResultsError("settings", f"the {controller_label(controller)} needs a "
                           "calibration: the trial has none; give settings.calibration "
                           "[offset_left, offset_right] (rad)")
    try:
        spec = ControllerSpec(
            controller, config,
            models=set_document(db, ModelSetRecord, model_set_id or trial.model_set_id,
                             "model_set_id") if sets else None,
            utilities=set_document(db, UtilitySetRecord, utility_set_id or trial.utility_set_id,
                                "utility_set_id") if sets else None)
        ctl = make_from_spec(spec)
    except ValueError as exc:
        raise ResultsError("controller", str(exc)) from exc
    t = cols.time()
    q = np.column_stack([cols.float_("q_raw_left"), cols.float_("q_raw_right")])
    truth_cols = "truth_activity" in cols and has_truth(cols)
    rec = AngleRecording(t, q, cols.str_("truth_activity").tolist() if truth_cols else None,
                         cols.int_("truth_lift") if truth_cols else None)
    replayed = TickData(replay_columns(rec, ctl, config.precompression_pct))
    truth = ground_truth(cols, trial.task, trial_segments(db, trial.id))
    original = summary(evaluate_lifts(cols, truth.lifts,
                                      registry.estimates_intent(trial.controller)),
                       cols, truth.gait, trial.controller)
    again = summary(evaluate_lifts(replayed, truth.lifts, registry.estimates_intent(controller)),
                    replayed, truth.gait, controller)
    return WhatIfOut.model_validate({
            "trial_id": trial.id, "truth": truth.source, "truth_note": truth.note,
            "original": original, "replay": again,
            "replay_config": {"controller": controller, "settings": config.to_json(),
                              "model_set_id": (model_set_id or trial.model_set_id)
                              if spec.models else None,
                              "utility_set_id": (utility_set_id or trial.utility_set_id)
                              if spec.utilities else None}})
