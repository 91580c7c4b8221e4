"""A study's results from its stored trials: the glue between the database and
`controller.evaluation`.

The evaluation package knows nothing of SQL; this module reads a trial's ticks and the
experimenter's segments, has `controller.evaluation.ground_truth` decide its lifts,
labels it with its participant and controller and hands it over, so the API, the
virtual study and the exports compute the paper's metrics one way. The what-if replay
(`what_if`) and the leave-one-participant-out evaluation (`model_evaluation`) read
trials through the same functions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import tick_queries
from backend.analysis.markers import trial_markers
from backend.db.evidence_tables import ModelSetRecord, Trial, TrialSegment, UtilitySetRecord
from backend.db.models import (
    ConditionLabel,
    Participant,
    Preference,
    QuestionnaireResponse,
    StudySession,
)
from backend.live import trial_quality
from backend.schemas.results import StudyResultsOut
from backend.schemas.wearers import LONG_USE_TASK
from controller.evaluation.columns import TickData
from controller.evaluation.ground_truth import NO_TRUTH, TrialTruth, ground_truth
from controller.evaluation.study import (
    RecordingEvaluation,
    controller_label,
    evaluate_recording,
    in_order,
    table_conditions,
)
from controller.evaluation.tables import (
    FalsePositiveTable,
    PerformanceTable,
    QuestionnaireScore,
    QuestionnaireTable,
    Table,
    lift_table,
    onset_to_lock_table,
)
from controller.intent.motion_model import ModelSet

if TYPE_CHECKING:
    from controller.evaluation.rendering import RenderedFigure

#: Table names served under `/api/studies/{id}/results/{table}.csv|.md`.
TABLE_NAMES = ("performance", "performance_by_kind", "false_positives", "questionnaires",
               "onset_to_lock", "lifts")
FIGURE_NAMES = ("peak_torques", "onset_to_lock")


class ResultsError(ValueError):
    """A request the stored data cannot answer; the message names the field."""

    def __init__(self, field_name: str, problem: str) -> None:
        super().__init__(f"{field_name}: {problem}")
        self.field_name = field_name
        self.problem = problem


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
    #: The trial's condition key ("umc+personal"; the controller's name for the
    #: population models with equal priors): what its evaluation is labelled with.
    condition: str = ""


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

    def columns(self, intent_only: bool = False) -> tuple[str, ...]:
        """The conditions the tables show (`table_conditions`), from the trials' and the
        questionnaires' (a condition answered but not yet evaluated still shows)."""
        present = {t.condition for t in self.trials}
        present |= {s.controller for s in self.questionnaire_scores}
        return table_conditions(present, intent_only)

    def answered(self) -> tuple[str, ...]:
        """The questionnaire table's rows: `columns`, then any other condition scored (a
        blinded baseline's), so that no answer is left out."""
        return tuple(dict.fromkeys([*self.columns(),
                                    *(s.controller for s in self.questionnaire_scores)]))

    def table(self, name: str) -> Table:
        """One of `TABLE_NAMES` as a `Table` (the paper's wide layout where it has one)."""
        evs = self.evaluations
        if name == "performance":
            return PerformanceTable.from_evaluations(evs, self.columns(True)).wide()
        if name == "performance_by_kind":
            return PerformanceTable.from_evaluations(evs, self.columns(True),
                                                     by_kind=True).long()
        if name == "false_positives":
            return FalsePositiveTable.from_evaluations(evs, self.columns()).wide()
        if name == "questionnaires":
            return QuestionnaireTable.from_scores(self.questionnaire_scores, self.preferences,
                                                  self.answered()).wide()
        if name == "onset_to_lock":
            return onset_to_lock_table(evs, controllers=self.columns())
        if name == "lifts":
            return lift_table(evs)
        raise ResultsError("table", f"unknown table {name!r}; choose one of "
                           f"{', '.join(TABLE_NAMES)}")

    def csv(self, name: str) -> str:
        """A table as CSV: the long form (every count) where the paper's is wide."""
        evs = self.evaluations
        if name == "performance":
            return PerformanceTable.from_evaluations(evs, self.columns(True)).to_csv()
        if name == "false_positives":
            return FalsePositiveTable.from_evaluations(evs, self.columns()).to_csv()
        if name == "questionnaires":
            return QuestionnaireTable.from_scores(self.questionnaire_scores, self.preferences,
                                                  self.answered()).to_csv()
        return self.table(name).to_csv()

    def markdown(self, name: str) -> str:
        """A table as Markdown, in the paper's layout."""
        return self.table(name).to_markdown()

    def figure(self, name: str) -> RenderedFigure:
        """One of `FIGURE_NAMES`, rendered as PNG and SVG."""
        # Matplotlib only when a figure is drawn: importing it costs every server start.
        from controller.evaluation.figures import onset_to_lock_figure, peak_torque_figure
        from controller.evaluation.rendering import render_figure
        evs = [e for e in self.evaluations if e.lifts]
        order = in_order(evs, self.columns())  # the tables' order, then any other
        if name == "peak_torques":
            return render_figure(peak_torque_figure(evs, controllers=order))
        if name == "onset_to_lock":
            return render_figure(onset_to_lock_figure(evs, controllers=order))
        raise ResultsError("figure", f"unknown figure {name!r}; choose one of "
                           f"{', '.join(FIGURE_NAMES)}")


# --------------------------------------------------------------------------- one trial


#: The tick fields `ground_truth` reads. A caller of `trial_columns` names the fields
#: it reads, to have them in one query (`tick_queries.run_ticks`); any other is read when
#: first needed.
GROUND_TRUTH_FIELDS = ("t", "truth_activity", "truth_lift")
#: The tick fields a trial's evaluation reads (`ground_truth`, `evaluate_recording`).
EVALUATION_FIELDS = (*GROUND_TRUTH_FIELDS, "controller_ran", "action", "lock_left",
                     "lock_right", "torque_left", "torque_right", "post_squat",
                     "post_stoop_left", "post_stoop_right")
#: The tick fields the timeline figure reads (its ground truth and five panels).
TIMELINE_FIELDS = (*GROUND_TRUTH_FIELDS, "q_left", "q_right", "action", "lock_left",
                   "lock_right", "post_squat", "post_stoop_left", "post_stoop_right",
                   "post_other", "s_curr_squat", "s_curr_stoop_left", "s_curr_stoop_right")


def trial_columns(engine: Engine, trial: Trial, fields: Sequence[str] = ()) -> TickData:
    """The trial's stored ticks as checked columns (empty if it never ran): `fields`
    (what the caller reads) in one query, any other field when first needed (an output
    reads a handful of the 55), up to the last tick stored now."""
    return tick_queries.run_ticks(engine, trial.run_id, fields)


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
    cols = trial_columns(engine, trial, EVALUATION_FIELDS)
    truth = ground_truth(cols, trial.task, trial_segments(db, trial.id))
    part = _participant_of(db, trial)
    condition = trial.condition or trial.controller
    ev = evaluate_recording(cols, part.code, condition, truth.lifts, truth.gait,
                            recording=f"trial-{trial.id}")
    return TrialResult(trial.id, part.code, trial.controller, trial.task, truth, ev,
                       dict(trial.quality_flags or {}), condition)


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


def counted(study_id: int, site: str | None) -> Any:
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
    participants = list(db.scalars(select(Participant).where(counted(study_id, site))
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
                    "controller": t.controller, "condition": t.condition,
                    "task": t.task, "truth": t.truth.source,
                    "truth_note": t.truth.note, "lifts": len(t.truth.lifts),
                    "incomplete_lifts": t.truth.incomplete_lifts,
                    "gait_trials": len(t.truth.gait),
                    "quality_flags": t.quality_flags} for t in res.trials],
        "skipped": res.skipped,
        "notes": notes,
    })


# --------------------------------------------------------------------------- timeline


def timeline_figure(engine: Engine, db: Session, trial: Trial) -> RenderedFigure:
    """The five-panel controller output of the whole trial, with its model set."""
    # Matplotlib and SciPy only when a figure is drawn: importing them costs every start.
    from controller.evaluation.rendering import render_figure
    from controller.evaluation.timeline import controller_output_figure
    cols = trial_columns(engine, trial, TIMELINE_FIELDS)
    if len(cols) == 0:
        raise ResultsError("status", f"trial {trial.id} has no stored ticks")
    truth = ground_truth(cols, trial.task, trial_segments(db, trial.id))
    models = None
    if trial.model_set_id is not None:
        ms = db.get(ModelSetRecord, trial.model_set_id)
        if ms is not None and ms.document is not None:
            models = ModelSet.from_json(ms.document)
    part = _participant_of(db, trial)
    shown = controller_label(trial.condition or trial.controller)
    title = f"Trial {trial.id}: {part.code}, {shown}, {trial.task}"
    marks = [(m.t, m.label) for m in trial_markers(db, trial.id)
             if m.t is not None and m.source != "system"]
    return render_figure(controller_output_figure(cols, models=models, lifts=truth.lifts,
                                                  title=title, markers=marks))


# --------------------------------------------------------------------------- sets


def set_document(db: Session, model: type[ModelSetRecord] | type[UtilitySetRecord],
                 ref: int | None, field_name: str) -> dict[str, Any]:
    """The JSON document of a ready model or utility set (`ref`), for a replay; a
    `ResultsError` naming `field_name` when there is none."""
    row = None
    if ref is not None:
        row = db.get(ModelSetRecord, ref) if model is ModelSetRecord else db.get(
            UtilitySetRecord, ref)
    if row is None or row.document is None:
        raise ResultsError(field_name, f"{ref} is not a ready set" if ref is not None
                           else "the controller needs one and the trial has none")
    return row.document
