"""The paper's tables, from a study's recording evaluations, as CSV and Markdown.

Every table has two views: `long()`, one row per participant, controller and group
with every count (what a statistics package wants, written by `to_csv()`), and
`wide()`, the paper's layout with participants as columns (written by
`to_markdown()`). Where one participant used several controllers, a wide cell lists
them separated by "/" in the table's controller order, as the paper's "10/10" for
UMC/E-UMC; "/" alone means the participant has no data for that row, and "-" a count
that does not apply (recognitions of a controller without intent estimation).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from controller import spreadsheet
from controller.evaluation.lifts import LIFT_KINDS, TRIAL_KINDS
from controller.evaluation.metrics import (
    DecisionOutcome,
    LiftOutcome,
    summarise_onset_to_lock,
)
from controller.evaluation.study import RecordingEvaluation, controller_label, in_order
from controller.tick_record import ACTION_NAMES

Cell = str | int | float | bool | None

#: The paper groups stoop left and stoop right as asymmetric stoops (AS).
PAPER_MOTION_GROUPS: dict[str, str] = {"squat": "SQ", "stoop_left": "AS", "stoop_right": "AS"}
TRIAL_LABELS: dict[str, str] = {"walking": "W", "stair_walking": "SW"}
NOT_APPLICABLE = "/"


def _unique(values: Iterable[str]) -> list[str]:
    return list(dict.fromkeys(values))


def _csv_cell(v: Cell) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def _md_cell(v: Cell, float_format: str) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "" if math.isnan(v) else format(v, float_format)
    return str(v).replace("|", "\\|")


@dataclass(frozen=True)
class Table:
    """A plain table: a header and rows of cells.

    CSV writes raw values (floats in full precision, NaN and None empty, booleans as
    true/false). Markdown writes floats with `float_format`, an optional bold title
    above and notes below.
    """

    header: tuple[str, ...]
    rows: tuple[tuple[Cell, ...], ...]
    title: str = ""
    notes: tuple[str, ...] = ()
    float_format: str = ".3f"

    def __post_init__(self) -> None:
        for i, row in enumerate(self.rows):
            if len(row) != len(self.header):
                raise ValueError(
                    f"row {i} has {len(row)} cells, the header {len(self.header)}"
                )

    def to_csv(self) -> str:
        """Comma-separated values with a header line, newline-terminated."""
        return spreadsheet.table_text(self.header,
                                      ([_csv_cell(v) for v in row] for row in self.rows))

    def to_markdown(self) -> str:
        """A GitHub-flavoured Markdown table."""
        lines: list[str] = []
        if self.title:
            lines += [f"**{self.title}**", ""]
        lines.append("| " + " | ".join(h.replace("|", "\\|") for h in self.header) + " |")
        lines.append("|" + "|".join(" --- " for _ in self.header) + "|")
        for row in self.rows:
            lines.append("| " + " | ".join(_md_cell(v, self.float_format) for v in row) + " |")
        if self.notes:
            lines.append("")
            lines += self.notes
        return "\n".join(lines) + "\n"


#: A condition a participant did not run, inside a wide cell ("3/–/2"): an en dash, as
#: "-" is a value the controller did not compute and "n/a" would read as two cells.
NOT_RUN = "\u2013"


def _join(values: Sequence[str | None]) -> str:
    """One wide cell: a value per column of the title, in its order. Columns the
    participant did not run at the end are left out (the paper's cells: "3" where only
    the UMC ran, "3/2" where the E-UMC did too); one inside is `NOT_RUN`, so every value
    stays under its own column."""
    vals = list(values)
    while vals and vals[-1] is None:
        vals.pop()
    return "/".join(NOT_RUN if v is None else v for v in vals) if vals else NOT_APPLICABLE


# --------------------------------------------------------------------------- performance


@dataclass(frozen=True, slots=True)
class PerformanceRow:
    """Counts of one participant, controller and motion group.

    `recognised` is None for a controller without intent estimation (the PEC).
    `correct`, `wrong`, `missed` follow the paper's counting rule; `first_correct` is
    the stricter first-decision reading and `first_one_sided` the lifts whose first
    lock decision locked one side only (for squats: the delayed second side); see
    `controller.evaluation.metrics`.
    """

    participant: str
    controller: str
    motion: str
    lifts: int
    recognised: int | None
    correct: int
    wrong: int
    missed: int
    first_correct: int = 0
    first_one_sided: int = 0


@dataclass(frozen=True)
class PerformanceTable:
    """The paper's "Intent estimation and decision performance" table, with the wrong
    and missed decisions the paper does not show."""

    rows: tuple[PerformanceRow, ...]
    participants: tuple[str, ...]
    controllers: tuple[str, ...]
    motions: tuple[str, ...]

    @classmethod
    def from_evaluations(
        cls,
        evaluations: Sequence[RecordingEvaluation],
        controllers: Sequence[str] | None = None,
        by_kind: bool = False,
    ) -> PerformanceTable:
        """Count recognitions and decisions per participant, controller and motion.

        Args:
            evaluations: the study's recordings (those without lifts are ignored).
            controllers: which controllers, in which order (default: all, in order of
                appearance). The paper's table is `("umc", "eumc")`.
            by_kind: one row per lift kind instead of the paper's SQ and AS groups.
        """
        evs = [e for e in evaluations if e.lifts]
        ctls = _unique(e.controller for e in evs) if controllers is None else list(controllers)
        evs = [e for e in evs if e.controller in ctls]
        groups = {k: k for k in LIFT_KINDS} if by_kind else PAPER_MOTION_GROUPS
        motions = _unique(groups[k] for k in LIFT_KINDS)
        participants = _unique(e.participant for e in evs)
        outcomes: dict[tuple[str, str, str], list[LiftOutcome]] = {}
        for e in evs:
            for m in motions:
                outcomes.setdefault((e.participant, e.controller, m), [])
        for e in evs:
            for o in e.lifts:
                outcomes[(e.participant, e.controller, groups[o.lift.kind])].append(o)
        rows: list[PerformanceRow] = []
        for p in participants:
            for c in ctls:
                for m in motions:
                    if (p, c, m) not in outcomes:
                        continue
                    os_ = outcomes[(p, c, m)]
                    rec = [o.recognised for o in os_]
                    recognised = None if os_ and all(r is None for r in rec) else sum(
                        1 for r in rec if r
                    )
                    dec = [o.decision for o in os_]
                    rows.append(
                        PerformanceRow(
                            p, c, m, len(os_), recognised,
                            dec.count(DecisionOutcome.CORRECT),
                            dec.count(DecisionOutcome.WRONG),
                            dec.count(DecisionOutcome.MISSED),
                            sum(1 for o in os_ if o.first_decision is DecisionOutcome.CORRECT),
                            sum(1 for o in os_ if o.first_lock_one_sided),
                        )
                    )
        return cls(tuple(rows), tuple(participants), tuple(ctls), tuple(motions))

    def long(self) -> Table:
        """One row per participant, controller and motion with every count."""
        return Table(
            ("participant", "controller", "motion", "lifts", "recognised", "correct",
             "wrong", "missed", "first_correct", "first_one_sided"),
            tuple(
                (r.participant, r.controller, r.motion, r.lifts, r.recognised, r.correct,
                 r.wrong, r.missed, r.first_correct, r.first_one_sided)
                for r in self.rows
            ),
            title="Intent estimation and decision performance",
        )

    def wide(self) -> Table:
        """The paper's layout: metric and motion as rows, participants as columns."""
        index = {(r.participant, r.controller, r.motion): r for r in self.rows}
        metrics: list[tuple[str, str]] = [
            ("Intent estimation", "recognised"),
            ("Decision correct", "correct"),
            ("Decision wrong", "wrong"),
            ("Decision missed", "missed"),
            ("First decision correct", "first_correct"),
            ("First lock one-sided", "first_one_sided"),
        ]
        squat_groups = {PAPER_MOTION_GROUPS["squat"], "squat"}
        rows: list[tuple[Cell, ...]] = []
        for label, attr in metrics:
            for m in self.motions:
                if attr == "first_one_sided" and m not in squat_groups:
                    continue  # a one-sided first lock is the correct one in a stoop
                cells: list[Cell] = [label, m]
                for p in self.participants:
                    vals: list[str | None] = []
                    for c in self.controllers:
                        r = index.get((p, c, m))
                        if r is None:
                            vals.append(None)
                            continue
                        v = getattr(r, attr)
                        vals.append("-" if v is None else str(v))  # "n/a" would read as two cells
                    cells.append(_join(vals))
                rows.append(tuple(cells))
        labels = "/".join(controller_label(c) for c in self.controllers)
        lifts = sorted({r.lifts for r in self.rows})
        return Table(
            ("Metric", "Motion", *self.participants),
            tuple(rows),
            title=f"Intent estimation and decision performance ({labels})",
            notes=(
                f"Cells list {labels} where a participant used several controllers "
                f"({NOT_RUN} for one not run before another that was). "
                f"Lifts per cell: {', '.join(map(str, lifts)) or 'none'}. "
                "Recognised: the correct model's posterior reached 0.5 in the first half "
                "of the lift. Decision (the paper's rule): squat correct if both sides "
                "were commanded to lock in the first half (in one decision or two), wrong "
                "if one side only, missed if none; stoop correct if the first lock "
                "decision in the first half is the supporting side. First decision: the "
                "first lock decision alone must be the correct action. First lock "
                "one-sided: squats whose first lock decision locked one side only.",
            ),
        )

    def to_csv(self) -> str:
        """`long()` as CSV."""
        return self.long().to_csv()

    def to_markdown(self) -> str:
        """`wide()` as Markdown."""
        return self.wide().to_markdown()


# --------------------------------------------------------------------------- false positives


@dataclass(frozen=True, slots=True)
class FalsePositiveRow:
    """False positives of one participant, controller and trial kind, summed over its
    trials (see `controller.evaluation.metrics.FalsePositives` for each count)."""

    participant: str
    controller: str
    trial: str
    trials: int
    signals: int
    edges_left: int
    edges_right: int
    decisions: int
    lock_ticks: int
    duration_s: float


@dataclass(frozen=True)
class FalsePositiveTable:
    """The paper's "Number of false positive lock signals" table."""

    rows: tuple[FalsePositiveRow, ...]
    participants: tuple[str, ...]
    controllers: tuple[str, ...]

    @classmethod
    def from_evaluations(
        cls,
        evaluations: Sequence[RecordingEvaluation],
        controllers: Sequence[str] | None = None,
    ) -> FalsePositiveTable:
        """Sum the false positives per participant, controller and trial kind.

        Args:
            evaluations: the study's recordings (those without trials are ignored).
            controllers: which controllers, in which order (default: all, in order of
                appearance; the paper's is `("pec", "umc", "eumc")`).
        """
        evs = [e for e in evaluations if e.false_positives]
        ctls = _unique(e.controller for e in evs) if controllers is None else list(controllers)
        evs = [e for e in evs if e.controller in ctls]
        participants = _unique(e.participant for e in evs)
        acc: dict[tuple[str, str, str], list[int | float]] = {}
        for e in evs:
            for fp in e.false_positives:
                a = acc.setdefault((e.participant, e.controller, fp.trial.kind), [0] * 7)
                for i, v in enumerate(
                    (1, fp.signals, fp.edges_left, fp.edges_right, fp.decisions,
                     fp.lock_ticks, fp.duration_s)
                ):
                    a[i] += v
        rows = [
            FalsePositiveRow(p, c, k, int(s[0]), int(s[1]), int(s[2]), int(s[3]), int(s[4]),
                             int(s[5]), float(s[6]))
            for p in participants
            for c in ctls
            for k in TRIAL_KINDS
            if (s := acc.get((p, c, k))) is not None
        ]
        return cls(tuple(rows), tuple(participants), tuple(ctls))

    def long(self) -> Table:
        """One row per participant, controller and trial kind with every count."""
        return Table(
            ("participant", "controller", "trial", "trials", "signals", "edges_left",
             "edges_right", "decisions", "lock_ticks", "duration_s"),
            tuple(
                (r.participant, r.controller, r.trial, r.trials, r.signals, r.edges_left,
                 r.edges_right, r.decisions, r.lock_ticks, r.duration_s)
                for r in self.rows
            ),
            title="False positive lock signals",
        )

    def wide(self) -> Table:
        """The paper's layout: controller and trial (W, SW) as rows, participants as
        columns, the `signals` count in each cell."""
        index = {(r.participant, r.controller, r.trial): r for r in self.rows}
        rows: list[tuple[Cell, ...]] = []
        for c in self.controllers:
            for k in TRIAL_KINDS:
                cells: list[Cell] = [controller_label(c), TRIAL_LABELS[k]]
                for p in self.participants:
                    r = index.get((p, c, k))
                    cells.append(NOT_APPLICABLE if r is None else str(r.signals))
                rows.append(tuple(cells))
        return Table(
            ("Controller", "Trial", *self.participants),
            tuple(rows),
            title="Number of false positive lock signals",
            notes=(
                "W: walking, SW: stair walking. A lock signal is a rising edge of the "
                "held lock command on either side; / means no such trial.",
            ),
        )

    def to_csv(self) -> str:
        """`long()` as CSV."""
        return self.long().to_csv()

    def to_markdown(self) -> str:
        """`wide()` as Markdown."""
        return self.wide().to_markdown()


# --------------------------------------------------------------------------- per lift


def lift_table(evaluations: Sequence[RecordingEvaluation]) -> Table:
    """Every per-lift metric, one row per lift: the data behind the peak torque
    scatter and the onset-to-lock histogram."""
    rows: list[tuple[Cell, ...]] = []
    for e in evaluations:
        for o in e.lifts:
            lf = o.lift
            rows.append(
                (
                    e.participant, e.controller, e.recording, lf.index, lf.kind, lf.start,
                    lf.end, o.recognised, o.peak_posterior, o.decision.value,
                    o.first_decision.value, o.first_lock_one_sided, o.sides_commanded,
                    None if o.first_action is None else ACTION_NAMES[o.first_action - 1],
                    o.first_decision_s, o.peak_torque_left, o.peak_torque_right,
                    o.first_lock_s, o.correct_lock_s,
                )
            )
    return Table(
        ("participant", "controller", "recording", "lift", "kind", "start", "end",
         "recognised", "peak_posterior", "decision", "first_decision", "first_lock_one_sided",
         "sides_commanded", "first_action", "first_decision_s",
         "peak_torque_left_nm", "peak_torque_right_nm", "first_lock_s", "correct_lock_s"),
        tuple(rows),
        title="Per-lift outcomes",
    )


def onset_to_lock_table(
    evaluations: Sequence[RecordingEvaluation], by_kind: bool = True,
    controllers: Sequence[str] | None = None,
) -> Table:
    """Median and IQR of onset-to-lock times per controller (and lift kind, plus all
    kinds together), for the first lock on either side and for the correct side(s).
    `controllers`: their order (default: as they appear); any other with lifts follows."""
    rows: list[tuple[Cell, ...]] = []
    for c in in_order(evaluations, controllers):
        outs = [o for e in evaluations if e.controller == c for o in e.lifts]
        kinds: list[str] = [k for k in LIFT_KINDS if any(o.lift.kind == k for o in outs)]
        for k in [*kinds, "all"] if by_kind else ["all"]:
            sel = outs if k == "all" else [o for o in outs if o.lift.kind == k]
            first = summarise_onset_to_lock(sel, "first")
            corr = summarise_onset_to_lock(sel, "correct")
            rows.append(
                (
                    controller_label(c), k, first.n_lifts,
                    first.n_locked, first.median_s, first.q25_s, first.q75_s,
                    corr.n_locked, corr.median_s, corr.q25_s, corr.q75_s,
                )
            )
    return Table(
        ("controller", "motion", "lifts", "first_locked", "first_median_s", "first_q25_s",
         "first_q75_s", "correct_locked", "correct_median_s", "correct_q25_s",
         "correct_q75_s"),
        tuple(rows),
        title="Time from lift onset to lock",
        notes=(
            "first: held command on either side; correct: the supporting side held "
            "(squat: both sides). Quartiles over the lifts that locked.",
        ),
    )


# --------------------------------------------------------------------------- questionnaires


@dataclass(frozen=True, slots=True)
class QuestionnaireScore:
    """One participant's score on one instrument ("SUS", "EUS") for one controller."""

    participant: str
    controller: str
    instrument: str
    score: float


_NO_PREFERENCE = frozenset({"", "/", "none", "no preference", "no_preference", "-"})


@dataclass(frozen=True)
class QuestionnaireTable:
    """The paper's "Questionnaire results" table: scores per instrument, controller and
    participant, the higher score of each participant and instrument marked, and the
    preference the participant stated when asked.

    A score is marked only when it is strictly higher than all of that participant's
    other scores on the instrument (the paper leaves the tie 6.35/6.35 unmarked) and
    there is something to compare it with.
    """

    scores: tuple[QuestionnaireScore, ...]
    preferences: tuple[tuple[str, str | None], ...]
    participants: tuple[str, ...]
    controllers: tuple[str, ...]
    instruments: tuple[str, ...]
    _index: dict[tuple[str, str, str], float] = field(
        init=False, repr=False, compare=False, default_factory=dict
    )

    def __post_init__(self) -> None:
        for s in self.scores:
            key = (s.participant, s.instrument, s.controller)
            if key in self._index:
                raise ValueError(f"two scores for participant {key[0]}, {key[1]}, {key[2]}")
            if not math.isfinite(s.score):
                raise ValueError(f"score of participant {key[0]}, {key[1]}, {key[2]} is not finite")
            self._index[key] = float(s.score)

    @classmethod
    def from_scores(
        cls,
        scores: Sequence[QuestionnaireScore],
        preferences: Mapping[str, str | None] | None = None,
        controllers: Sequence[str] | None = None,
    ) -> QuestionnaireTable:
        """Build the table.

        Args:
            scores: every score.
            preferences: participant to the controller they said they preferred; None,
                "" or "no preference" for none.
            controllers: row order (default: order of appearance; the paper's is
                `("pec", "umc")`).
        """
        prefs = dict(preferences or {})
        participants = _unique([s.participant for s in scores] + list(prefs))
        ctls = _unique(s.controller for s in scores) if controllers is None else list(controllers)
        norm: list[tuple[str, str | None]] = []
        for p in participants:
            v = prefs.get(p)
            norm.append((p, None if v is None or v.strip().lower() in _NO_PREFERENCE else v))
        return cls(
            tuple(scores),
            tuple(norm),
            tuple(participants),
            tuple(ctls),
            tuple(_unique(s.instrument for s in scores)),
        )

    def score(self, participant: str, instrument: str, controller: str) -> float | None:
        """A score, None if not given."""
        return self._index.get((participant, instrument, controller))

    def highest(self, participant: str, instrument: str) -> str | None:
        """The controller with the strictly highest score, None on a tie or with fewer
        than two scores."""
        vals = [
            (v, c)
            for c in self.controllers
            if (v := self.score(participant, instrument, c)) is not None
        ]
        if len(vals) < 2:
            return None
        best = max(v for v, _ in vals)
        winners = [c for v, c in vals if v == best]
        return winners[0] if len(winners) == 1 else None

    def preference(self, participant: str) -> str | None:
        """The stated preference, None for none."""
        return dict(self.preferences).get(participant)

    def long(self) -> Table:
        """One row per participant, instrument and controller."""
        rows: list[tuple[Cell, ...]] = []
        for p in self.participants:
            for ins in self.instruments:
                top = self.highest(p, ins)
                for c in self.controllers:
                    v = self.score(p, ins, c)
                    if v is not None:
                        rows.append((p, ins, c, v, c == top, self.preference(p)))
        return Table(
            ("participant", "instrument", "controller", "score", "highest",
             "stated_preference"),
            tuple(rows),
            title="Questionnaire results",
        )

    def wide(self) -> Table:
        """The paper's layout, the highest score per participant and instrument bold."""
        rows: list[tuple[Cell, ...]] = []
        for ins in self.instruments:
            for c in self.controllers:
                cells: list[Cell] = [ins, controller_label(c)]
                for p in self.participants:
                    v = self.score(p, ins, c)
                    if v is None:
                        cells.append(NOT_APPLICABLE)
                        continue
                    text = f"{v:g}"
                    cells.append(f"**{text}**" if self.highest(p, ins) == c else text)
                rows.append(tuple(cells))
        pref_cells: list[Cell] = ["Preference", ""]
        for p in self.participants:
            pref = self.preference(p)
            pref_cells.append(NOT_APPLICABLE if pref is None else controller_label(pref))
        rows.append(tuple(pref_cells))
        return Table(
            ("Instrument", "Controller", *self.participants),
            tuple(rows),
            title="Questionnaire results",
            notes=("Bold: the participant's highest score on that instrument.",),
        )

    def to_csv(self) -> str:
        """`long()` as CSV."""
        return self.long().to_csv()

    def to_markdown(self) -> str:
        """`wide()` as Markdown."""
        return self.wide().to_markdown()

