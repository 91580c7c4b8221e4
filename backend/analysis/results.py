"""A study's results from its stored trials: the glue between the database and
`controller.evaluation`.

The evaluation package knows nothing of SQL; this module reads a trial's ticks, decides
its ground truth, labels it with its participant and controller and hands it over, so
the API, the virtual study and the what-if replay compute the paper's metrics one way.

Ground truth, in order of preference:

1. the simulation's truth columns (`truth_lift`, `truth_activity`) when the ticks carry
   them (a simulated wearer);
2. the experimenter's lift segments of the trial (`trial_segments`, set through
   `/api/trials/{id}/segments`), the ground truth of a trial on hardware; a segment
   still "unlabelled" makes the trial wait (`truth: "none"`, the note says why) rather
   than count fewer lifts;
3. for a walking or stair-walking task, the whole trial as one gait trial (the paper
   recorded those trials on their own);
4. otherwise the lifts are unknown: the result says so (`truth: "none"`) instead of
   reporting zeros.

A trial starts and stops at arbitrary moments of the wearer's motion, so a lift that
was already under way at the first tick or still under way at the last one is
incomplete: it is left out (`incomplete_lifts` counts them), since its first half, the
window the paper's metrics look at, is not the lift's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import tick_queries
from backend.db.evidence_tables import (
    LiftSegment,
    ModelSetRecord,
    Recording,
    Trial,
    TrialSegment,
    UtilitySetRecord,
)
from backend.db.models import (
    ConditionLabel,
    Participant,
    Preference,
    QuestionnaireResponse,
    StudySession,
)
from backend.live import trial_quality
from backend.schemas.results import ModelEvaluationOut, StudyResultsOut, WhatIfOut
from backend.schemas.wearers import LONG_USE_TASK
from controller.config import ControllerConfig, SettingError
from controller.controllers import registry
from controller.controllers.factory import make_from_spec, needs_models
from controller.controllers.spec import ControllerSpec
from controller.evaluation import (
    DecisionOutcome,
    FalsePositiveTable,
    GaitTrial,
    Lift,
    LiftOutcome,
    PerformanceTable,
    QuestionnaireScore,
    QuestionnaireTable,
    RecordingEvaluation,
    Table,
    TickData,
    controller_label,
    controller_output_figure,
    evaluate_lifts,
    evaluate_recording,
    lift_table,
    lifts_from_segments,
    lifts_from_truth,
    onset_to_lock_figure,
    onset_to_lock_table,
    peak_torque_figure,
    render_figure,
    summarise_onset_to_lock,
    trials_from_truth,
    whole_recording_trial,
)
from controller.evaluation.rendering import RenderedFigure
from controller.intent.motion_model import ModelSet, fit_model_set
from controller.runner.replay import AngleRecording, replay_columns
from controller.tick_codec import FIELD_NAMES
from controller.tick_record import ACTION_NAMES, MODEL_NAMES, Action

TruthSource = Literal["simulation", "segments", "task", "none"]
#: The truth source of a trial whose lifts are unknown.
NO_TRUTH: TruthSource = "none"
#: Tasks whose whole trial is a gait trial when the ticks carry no truth.
GAIT_TASKS: dict[str, str] = {"walking": "walking", "stairs": "stair_walking",
                              "stair_walking": "stair_walking"}
#: Table names served under `/api/studies/{id}/results/{table}.csv|.md`.
TABLE_NAMES = ("performance", "performance_by_kind", "false_positives", "questionnaires",
               "onset_to_lock", "lifts")
FIGURE_NAMES = ("peak_torques", "onset_to_lock")


def table_controllers(intent_only: bool = False) -> tuple[str, ...]:
    """The planned controllers (`controller.controllers.registry.PlanPlace`) in the order of the
    paper's tables: those that estimate no intent first (the PEC), then the others by
    plan rank (UMC, E-UMC); `intent_only`: only those that estimate intent (the
    performance table: no intent, no recognised or correct lifts)."""
    regs = [r for r in registry.planned() if r.estimates_intent or not intent_only]
    return tuple(r.name for r in sorted(regs, key=lambda r: r.estimates_intent))


class ResultsError(ValueError):
    """A request the stored data cannot answer; the message names the field."""

    def __init__(self, field_name: str, problem: str) -> None:
        super().__init__(f"{field_name}: {problem}")
        self.field_name = field_name
        self.problem = problem


@dataclass(frozen=True)
class TrialTruth:
    """Lifts and gait trials of one trial's ticks, and where they came from."""

    source: TruthSource
    lifts: tuple[Lift, ...] = ()
    gait: tuple[GaitTrial, ...] = ()
    incomplete_lifts: int = 0
    note: str = ""


@dataclass(frozen=True)
class TrialResult:
    """One stored trial, evaluated."""

    trial_id: int
    participant: str
    controller: str
    task: str
    truth: TrialTruth
    evaluation: RecordingEvaluation
    #: Device time gaps or time going backwards (`backend.live.trial_quality`); {} if none.
    quality_flags: dict[str, Any] = field(default_factory=dict)


@dataclass
class StudyResults:
    """Every evaluated trial of a study and the tables built from them."""

    study_id: int
    trials: list[TrialResult] = field(default_factory=list)
    skipped: list[dict[str, Any]] = field(default_factory=list)
    questionnaire_scores: list[QuestionnaireScore] = field(default_factory=list)
    preferences: dict[str, str | None] = field(default_factory=dict)

    @property
    def evaluations(self) -> list[RecordingEvaluation]:
        """The evaluations in trial order."""
        return [t.evaluation for t in self.trials]

    def table(self, name: str) -> Table:
        """One of `TABLE_NAMES` as a `Table` (the paper's wide layout where it has one)."""
        evs = self.evaluations
        if name == "performance":
            return PerformanceTable.from_evaluations(evs, table_controllers(True)).wide()
        if name == "performance_by_kind":
            return PerformanceTable.from_evaluations(evs, table_controllers(True),
                                                     by_kind=True).long()
        if name == "false_positives":
            return FalsePositiveTable.from_evaluations(evs, table_controllers()).wide()
        if name == "questionnaires":
            return QuestionnaireTable.from_scores(self.questionnaire_scores, self.preferences,
                                                  table_controllers()).wide()
        if name == "onset_to_lock":
            return onset_to_lock_table(evs)
        if name == "lifts":
            return lift_table(evs)
        raise ResultsError("table", f"unknown table {name!r}; choose one of "
                           f"{', '.join(TABLE_NAMES)}")

    def csv(self, name: str) -> str:
        """A table as CSV: the long form (every count) where the paper's is wide."""
        evs = self.evaluations
        if name == "performance":
            return PerformanceTable.from_evaluations(evs, table_controllers(True)).to_csv()
        if name == "false_positives":
            return FalsePositiveTable.from_evaluations(evs, table_controllers()).to_csv()
        if name == "questionnaires":
            return QuestionnaireTable.from_scores(self.questionnaire_scores, self.preferences,
                                                  table_controllers()).to_csv()
        return self.table(name).to_csv()

    def markdown(self, name: str) -> str:
        """A table as Markdown, in the paper's layout."""
        return self.table(name).to_markdown()

    def figure(self, name: str) -> RenderedFigure:
        """One of `FIGURE_NAMES`, rendered as PNG and SVG."""
        evs = [e for e in self.evaluations if e.lifts]
        if name == "peak_torques":
            return render_figure(peak_torque_figure(evs))
        if name == "onset_to_lock":
            return render_figure(onset_to_lock_figure(evs))
        raise ResultsError("figure", f"unknown figure {name!r}; choose one of "
                           f"{', '.join(FIGURE_NAMES)}")


# --------------------------------------------------------------------------- one trial


def trial_columns(engine: Engine, trial: Trial) -> TickData:
    """The trial's stored ticks as checked columns (empty if it never ran)."""
    if trial.run_id is None:
        return TickData({})
    run_id = trial.run_id
    # Each column is read when an output first needs it: the tables read a handful of
    # the 55, and reading one is a fraction of the cost of reading all. Up to the last
    # tick stored now, so every column has the same ticks.
    last = tick_queries.tick_id_range(engine, run_id)[1]
    if last is None:
        return TickData({})
    t = tick_queries.columns(engine, run_id, last_id=last, fields=("t",))["t"]
    return TickData.on_demand(
        len(t), FIELD_NAMES,
        lambda name: tick_queries.columns(engine, run_id, last_id=last, fields=(name,))[name],
    ).with_columns({"t": t})


def _has_truth(cols: TickData) -> bool:
    if "truth_activity" not in cols or len(cols) == 0:
        return False
    return bool((cols.str_("truth_activity") != "").any())


def _renumbered(cols: TickData) -> TickData:
    """The columns with every contiguous run of one `truth_lift` value numbered anew.

    The simulated device loops its script, and each repetition numbers its lifts from
    0 again; a trial that spans the loop therefore holds lift 3 twice. Each run of ticks
    is one lift, whatever its number.
    """
    lift = cols.int_("truth_lift")
    new = np.full(lift.shape, -1, dtype=np.int64)
    k = 0
    start = 0
    n = lift.size
    while start < n:
        end = start
        while end + 1 < n and lift[end + 1] == lift[start]:
            end += 1
        if lift[start] >= 0:
            new[start:end + 1] = k
            k += 1
        start = end + 1
    return cols.with_columns({"truth_lift": new})


def ground_truth(cols: TickData, task: str,
                 segments: Sequence[tuple[int, int, str]] = ()) -> TrialTruth:
    """The lifts and gait trials of a trial's ticks (see the module docstring);
    `segments` are the experimenter's (start, end, label) of the trial."""
    n = len(cols)
    if n == 0:
        return TrialTruth("none", note="the trial has no stored ticks")
    if _has_truth(cols):
        every = lifts_from_truth(_renumbered(cols))
        complete = tuple(lf for lf in every if lf.start > 0 and lf.end < n - 1)
        gait = tuple(trials_from_truth(cols))
        return TrialTruth("simulation", complete, gait, len(every) - len(complete),
                           "lifts and gait trials from the simulation's truth columns")
    kind = GAIT_TASKS.get(task.strip().lower().replace("-", "_"))
    gait_trials = (whole_recording_trial(n, kind),) if kind is not None else ()
    if segments:
        try:
            lifts = tuple(lifts_from_segments(segments, n_ticks=n))
        except ValueError as exc:
            return TrialTruth("none", note=f"the experimenter's segments cannot be used "
                               f"yet: {exc}")
        return TrialTruth("segments", lifts, gait_trials,
                           note=f"{len(lifts)} lifts from the experimenter's segments")
    if kind is not None:
        return TrialTruth("task", (), gait_trials,
                           note=f"the whole trial is one {kind} trial (task {task!r})")
    return TrialTruth("none", note="lifts unknown: no truth columns and no experimenter "
                       "segments (POST /api/trials/{id}/segment proposes them)")


def trial_segments(db: Session, trial_id: int) -> list[tuple[int, int, str]]:
    """The experimenter's segments of a trial as (start, end, label)."""
    return [(s.start, s.end, s.label) for s in db.scalars(
        select(TrialSegment).where(TrialSegment.trial_id == trial_id)
        .order_by(TrialSegment.start))]


def _participant_of(db: Session, trial: Trial) -> Participant:
    sess = db.get(StudySession, trial.session_id)
    part = db.get(Participant, sess.participant_id) if sess is not None else None
    if part is None:
        raise ResultsError("trial", f"trial {trial.id} has no participant")
    return part


def evaluate_trial(engine: Engine, db: Session, trial: Trial) -> TrialResult:
    """Evaluate one stored trial against its ground truth."""
    cols = trial_columns(engine, trial)
    truth = ground_truth(cols, trial.task, trial_segments(db, trial.id))
    part = _participant_of(db, trial)
    ev = evaluate_recording(cols, part.code, trial.controller, truth.lifts, truth.gait,
                            recording=f"trial-{trial.id}")
    return TrialResult(trial.id, part.code, trial.controller, trial.task, truth, ev,
                       dict(trial.quality_flags or {}))


# --------------------------------------------------------------------------- a study


def _questionnaires(db: Session, participants: Sequence[Participant]
                    ) -> tuple[list[QuestionnaireScore], dict[str, str | None]]:
    """Scores unblinded through each participant's condition labels."""
    scores: list[QuestionnaireScore] = []
    prefs: dict[str, str | None] = {}
    for p in participants:
        key = {c.label: c.controller for c in db.scalars(
            select(ConditionLabel).where(ConditionLabel.participant_id == p.id))}
        for r in db.scalars(select(QuestionnaireResponse).where(
                QuestionnaireResponse.participant_id == p.id).order_by(QuestionnaireResponse.id)):
            ctl = key.get(r.condition_label or "")
            if ctl is not None:
                scores.append(QuestionnaireScore(p.code, ctl, r.instrument_key.upper(),
                                                 float(r.score)))
        last = db.scalars(select(Preference).where(Preference.participant_id == p.id)
                          .order_by(Preference.id.desc())).first()
        if last is not None:
            prefs[p.code] = key.get(last.choice)
    return scores, prefs


def _counted(study_id: int, site: str | None) -> Any:
    """The participants whose data results may use: not withdrawn (an "exclude" protocol
    keeps their rows but out of every result), and of `site` for a site-limited member."""
    cond = (Participant.study_id == study_id) & Participant.withdrawn_at.is_(None)
    return cond if site is None else cond & (Participant.site == site)


def study_results(engine: Engine, db: Session, study_id: int,
                  site: str | None = None) -> StudyResults:
    """Evaluate every completed trial of the study, in participant and planned order.

    Aborted, planned and running trials are listed in `skipped` with the reason.
    Withdrawn participants are left out, and with `site` everyone of another site.
    """
    out = StudyResults(study_id)
    participants = list(db.scalars(select(Participant).where(_counted(study_id, site))
                                   .order_by(Participant.id)))
    for p in participants:
        trials = db.scalars(select(Trial).join(StudySession, Trial.session_id == StudySession.id)
                            .where(StudySession.participant_id == p.id)
                            .order_by(StudySession.id, Trial.planned_order))
        for t in trials:
            if t.task == LONG_USE_TASK:  # no plan's condition: the per-wearer page's
                out.skipped.append({"trial_id": t.id, "status": t.status,
                                    "reason": "long use (see the participant's progress)"})
                continue
            if t.status != "completed" or t.run_id is None:
                out.skipped.append({"trial_id": t.id, "status": t.status,
                                    "reason": f"trial is {t.status}"})
                continue
            out.trials.append(evaluate_trial(engine, db, t))
    out.questionnaire_scores, out.preferences = _questionnaires(db, participants)
    return out


class ResultsCache:
    """The last few study evaluations, keyed by everything they read (`fingerprint`).

    The tables, figures and JSON of one study are often fetched together and evaluating
    reads every tick; an entry is reused only while nothing it depends on changed."""

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self._entries: dict[tuple[Any, ...], StudyResults] = {}

    def get(self, engine: Engine, db: Session, study_id: int,
            site: str | None) -> StudyResults:
        """The study's results for a caller limited to `site` (None: every site)."""
        key = fingerprint(db, study_id, site)
        hit = self._entries.get(key)
        if hit is None:
            hit = study_results(engine, db, study_id, site)
            if len(self._entries) >= self.size:
                self._entries.pop(next(iter(self._entries)))
            self._entries[key] = hit
        return hit


def fingerprint(db: Session, study_id: int, site: str | None = None) -> tuple[Any, ...]:
    """What the study's results depend on, cheaply: its trials' states and runs and its
    questionnaire answers. Equal fingerprints give equal results, so a caller may reuse
    an evaluation (reading every tick of a study takes seconds)."""
    trials = tuple(db.execute(
        select(Trial.id, Trial.status, Trial.run_id, Trial.ended_at)
        .join(StudySession, Trial.session_id == StudySession.id)
        .join(Participant, StudySession.participant_id == Participant.id)
        .where(_counted(study_id, site)).order_by(Trial.id)).all())
    people = select(Participant.id).where(_counted(study_id, site))
    answers = tuple(db.scalars(select(QuestionnaireResponse.id).where(
        QuestionnaireResponse.participant_id.in_(people)).order_by(
        QuestionnaireResponse.id)))
    prefs = tuple(db.scalars(select(Preference.id).where(
        Preference.participant_id.in_(people)).order_by(Preference.id)))
    segs = tuple(db.execute(select(TrialSegment.id, TrialSegment.updated_at)
                            .join(Trial, TrialSegment.trial_id == Trial.id)
                            .join(StudySession, Trial.session_id == StudySession.id)
                            .where(StudySession.participant_id.in_(people))
                            .order_by(TrialSegment.id)).all())
    labels = tuple(db.execute(select(ConditionLabel.participant_id, ConditionLabel.label,
                                     ConditionLabel.controller).where(
        ConditionLabel.participant_id.in_(people)).order_by(ConditionLabel.id)).all())
    return (study_id, site, trials, answers, prefs, labels, segs)


def _table_json(table: Table) -> dict[str, Any]:
    def cell(v: Any) -> Any:
        return None if isinstance(v, float) and math.isnan(v) else v

    return {"title": table.title, "header": list(table.header),
            "rows": [[cell(v) for v in r] for r in table.rows], "notes": list(table.notes)}


def results_document(res: StudyResults) -> StudyResultsOut:
    """The body of `GET /api/studies/{id}/results` (and `results.json` in the files)."""
    tables = {name: _table_json(res.table(name)) for name in TABLE_NAMES if name != "lifts"}
    no_truth = [t.trial_id for t in res.trials if t.truth.source == NO_TRUTH]
    notes = []
    if no_truth:
        notes.append(f"lifts unknown for trials {no_truth}: no truth columns and no "
                     "usable segments; they count in no lift table")
    if not res.questionnaire_scores:
        notes.append("no questionnaire responses in this study")
    for t in res.trials:
        if t.quality_flags:
            notes.append(f"trial {t.trial_id}: {trial_quality.describe(t.quality_flags)}")
    return StudyResultsOut.model_validate({
        "study_id": res.study_id,
        "tables": tables,
        "trials": [{"trial_id": t.trial_id, "participant": t.participant,
                    "controller": t.controller, "task": t.task, "truth": t.truth.source,
                    "truth_note": t.truth.note, "lifts": len(t.truth.lifts),
                    "incomplete_lifts": t.truth.incomplete_lifts,
                    "gait_trials": len(t.truth.gait),
                    "quality_flags": t.quality_flags} for t in res.trials],
        "skipped": res.skipped,
        "notes": notes,
    })


# --------------------------------------------------------------------------- metrics summary


def summary(outcomes: Sequence[LiftOutcome], cols: TickData, gait: Sequence[GaitTrial],
            controller: str) -> dict[str, Any]:
    """Headline numbers of one run: recognitions, decisions, false positives, locks."""
    from controller.evaluation import count_false_positives

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


# --------------------------------------------------------------------------- timeline


def timeline_figure(engine: Engine, db: Session, trial: Trial) -> RenderedFigure:
    """The five-panel controller output of the whole trial, with its model set."""
    cols = trial_columns(engine, trial)
    if len(cols) == 0:
        raise ResultsError("status", f"trial {trial.id} has no stored ticks")
    truth = ground_truth(cols, trial.task, trial_segments(db, trial.id))
    models = None
    if trial.model_set_id is not None:
        ms = db.get(ModelSetRecord, trial.model_set_id)
        if ms is not None and ms.document is not None:
            models = ModelSet.from_json(ms.document)
    part = _participant_of(db, trial)
    title = f"Trial {trial.id}: {part.code}, {controller_label(trial.controller)}, {trial.task}"
    from backend.analysis.markers import trial_markers

    marks = [(m.t, m.label) for m in trial_markers(db, trial.id)
             if m.t is not None and m.source != "system"]
    return render_figure(controller_output_figure(cols, models=models, lifts=truth.lifts,
                                                  title=title, markers=marks))


# --------------------------------------------------------------------------- what-if


def _document(db: Session, model: type[ModelSetRecord] | type[UtilitySetRecord],
              ref: int | None, field_name: str) -> dict[str, Any]:
    row = None
    if ref is not None:
        row = db.get(ModelSetRecord, ref) if model is ModelSetRecord else db.get(
            UtilitySetRecord, ref)
    if row is None or row.document is None:
        raise ResultsError(field_name, f"{ref} is not a ready set" if ref is not None
                           else "the controller needs one and the trial has none")
    return row.document


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
            models=_document(db, ModelSetRecord, model_set_id or trial.model_set_id,
                             "model_set_id") if sets else None,
            utilities=_document(db, UtilitySetRecord, utility_set_id or trial.utility_set_id,
                                "utility_set_id") if sets else None)
        ctl = make_from_spec(spec)
    except ValueError as exc:
        raise ResultsError("controller", str(exc)) from exc
    t = cols.time()
    q = np.column_stack([cols.float_("q_raw_left"), cols.float_("q_raw_right")])
    truth_cols = "truth_activity" in cols and _has_truth(cols)
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


# --------------------------------------------------------------------------- leave one out


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
    ms = db.get(ModelSetRecord, model_set_id)
    if ms is None or ms.document is None:
        raise ResultsError("model_set_id", f"model set {model_set_id} is not ready")
    if utility_set_id is None:
        utility_set_id = db.scalar(select(UtilitySetRecord.id).where(
            UtilitySetRecord.study_id == ms.study_id, UtilitySetRecord.status == "ready")
            .order_by(UtilitySetRecord.id.desc()))
    utilities = _document(db, UtilitySetRecord, utility_set_id, "utility_set_id")
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
