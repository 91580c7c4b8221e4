"""Leave-one-participant-out evaluation of a model set's motion models: refitted without
each participant whose segments it was fitted from, then scored on that participant's
recordings replayed through a UMC."""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import tick_queries
from backend.analysis.results import ResultsError, set_document
from backend.db.evidence_tables import LiftSegment, ModelSetRecord, Recording, UtilitySetRecord
from backend.db.models import Participant, StudySession
from backend.schemas.results import ModelEvaluationOut
from controller.config import ControllerConfig, SettingError
from controller.controllers.factory import make_from_spec
from controller.controllers.spec import ControllerSpec
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import lifts_from_segments
from controller.evaluation.metrics import DecisionOutcome, evaluate_lifts
from controller.intent.motion_model import fit_model_set
from controller.tick_record import ACTION_NAMES, MODEL_NAMES, Action


def _owner(db: Session, recording_id: int) -> str:
    rec = db.get(Recording, recording_id)
    sess = db.get(StudySession, rec.session_id) if rec else None
    part = db.get(Participant, sess.participant_id) if sess else None
    return part.code if part else "?"


def leave_one_participant_out(engine: Engine, db: Session, model_set_id: int,
                              utility_set_id: int | None = None,
                              rate_hz: float | None = None) -> ModelEvaluationOut:
    """Leave-one-participant-out evaluation of the motion models of a model set.

    For each participant whose segments the model set was fitted from, the models are
    fitted again (same latent dimension settings) from the other participants'
    segments only; the held-out participant's recordings are then replayed through a
    UMC with those models, and each held-out segment is scored with the paper's
    rules (recognised: correct posterior >= 0.5 in the first half; decision: first
    lock decision in the first half). Replaying whole recordings rather than cut-out
    segments keeps the standing before each lift, which the onset detection needs.

    The confusion matrices count, per true motion, which motion's posterior first
    reached 0.5 in the first half ("none" if none did) and which first lock decision
    was taken ("missed" if none).
    """
    # The batch replay on first use: it imports the simulated mechanism, whose compiled
    # kernels would otherwise load at every server start.
    from controller.runner.replay import AngleRecording, replay_columns

    ms = db.get(ModelSetRecord, model_set_id)
    if ms is None or ms.document is None:
        raise ResultsError("model_set_id", f"model set {model_set_id} is not ready")
    if utility_set_id is None:
        utility_set_id = db.scalar(select(UtilitySetRecord.id).where(
            UtilitySetRecord.study_id == ms.study_id, UtilitySetRecord.status == "ready")
            .order_by(UtilitySetRecord.id.desc()))
    utilities = set_document(db, UtilitySetRecord, utility_set_id, "utility_set_id")
    segs = list(db.scalars(select(LiftSegment).where(LiftSegment.id.in_(ms.segment_ids))))
    by_owner: dict[str, list[LiftSegment]] = {}
    for s in segs:
        if s.label in MODEL_NAMES:
            by_owner.setdefault(_owner(db, s.recording_id), []).append(s)
    if len(by_owner) < 2:
        raise ResultsError("model_set_id", "needs segments of at least two participants")
    angles: dict[int, np.ndarray] = {}
    for rid in {s.recording_id for s in segs}:
        rec = db.get(Recording, rid)
        assert rec is not None and rec.run_id is not None
        c = tick_queries.columns(engine, rec.run_id, rec.first_tick_id, rec.last_tick_id)
        # Fit on q_left/right as the model-set job does; replay the raw angles, as a
        # live UMC reads them.
        angles[rid] = np.column_stack([c["t"], c["q_raw_left"], c["q_raw_right"],
                                       c["q_left"], c["q_right"]])
    try:
        config = ControllerConfig() if rate_hz is None else ControllerConfig().at_rate(rate_hz)
    except SettingError as exc:
        raise ResultsError("rate_hz", exc.problem) from exc
    params = ms.params or {}
    predicted_names = [*MODEL_NAMES, "none"]
    decision_names = [ACTION_NAMES[a - 1] for a in (Action.LOCK_BOTH, Action.LOCK_LEFT,
                                                    Action.LOCK_RIGHT)] + ["missed"]
    recog = {m: dict.fromkeys(predicted_names, 0) for m in MODEL_NAMES}
    decide = {m: dict.fromkeys(decision_names, 0) for m in MODEL_NAMES}
    folds: list[dict[str, Any]] = []
    for held, mine in sorted(by_owner.items()):
        demos: dict[str, list[np.ndarray]] = {m: [] for m in MODEL_NAMES}
        for other, theirs in by_owner.items():
            if other == held:
                continue
            for s in theirs:
                demos[s.label].append(angles[s.recording_id][s.start:s.end + 1, 3:5])
        short = {m: len(v) for m, v in demos.items() if len(v) < 2}
        if short:
            folds.append({"participant": held, "error": f"too few training segments {short}"})
            continue
        mset = fit_model_set(demos, q=params.get("latent_dim"),
                             **({"explained_variance": params["explained_variance"]}
                                if params.get("explained_variance") else {}),
                             version=f"lopo-{held}")
        fold: dict[str, Any] = {"participant": held, "segments": 0, "recognised": 0,
                                "correct": 0}
        for rid in sorted({s.recording_id for s in mine}):
            a = angles[rid]
            ctl = make_from_spec(ControllerSpec("umc", config, models=mset.to_json(),
                                                utilities=utilities))
            cols = TickData(replay_columns(AngleRecording(a[:, 0], a[:, 1:3], None, None), ctl,
                                           config.precompression_pct))
            lifts = lifts_from_segments([(s.start, s.end, s.label) for s in mine
                                         if s.recording_id == rid], len(cols))
            post = {m: cols.float_(f"post_{m}") for m in MODEL_NAMES}
            for o in evaluate_lifts(cols, lifts, True):
                lf = o.lift
                first = None
                best_k = None
                for m in MODEL_NAMES:
                    hit = np.flatnonzero(post[m][lf.first_half] >= 0.5)
                    if hit.size and (best_k is None or hit[0] < best_k):
                        best_k, first = int(hit[0]), m
                recog[lf.kind][first or "none"] += 1
                decide[lf.kind]["missed" if o.first_action is None
                                else ACTION_NAMES[o.first_action - 1]] += 1
                fold["segments"] += 1
                fold["recognised"] += int(bool(o.recognised))
                fold["correct"] += int(o.decision == DecisionOutcome.CORRECT)
        folds.append(fold)
    n = sum(int(f.get("segments", 0)) for f in folds)
    return ModelEvaluationOut.model_validate({
        "model_set_id": model_set_id, "utility_set_id": utility_set_id,
        "settings": config.to_json(), "participants": sorted(by_owner), "folds": folds,
        "segments": n,
        "recognition_accuracy": (sum(int(f.get("recognised", 0)) for f in folds) / n
                                 if n else None),
        "decision_accuracy": (sum(int(f.get("correct", 0)) for f in folds) / n
                              if n else None),
        "recognition_confusion": recog, "decision_confusion": decide,
    })
