"""Ground truth for the evaluation: which ticks were which lift, which were a gait trial.

Two sources give the same objects, so every metric is computed one way:

- the simulation's truth columns (`truth_activity`, `truth_lift`) via
  `lifts_from_truth` and `trials_from_truth`;
- an experimenter's segments (start and end tick index plus a label), the paper's
  manual segmentation, via `lifts_from_segments`, and `whole_recording_trial` for a
  recording that is one walking or stair-walking trial, as in the paper.

Indices are tick (sample) indices into the recording, `end` inclusive, like
`controller.intent.segmentation.SegmentedLift`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from controller.evaluation.columns import Columns, TickData
from controller.sim.activity_kinds import GAIT_KINDS
from controller.tick_record import MODEL_NAMES, Action

LiftKind = Literal["squat", "stoop_left", "stoop_right"]
TrialKind = Literal["walking", "stair_walking"]
LIFT_KINDS: tuple[LiftKind, LiftKind, LiftKind] = ("squat", "stoop_left", "stoop_right")
TRIAL_KINDS: tuple[TrialKind, TrialKind] = ("walking", "stair_walking")
assert LIFT_KINDS == MODEL_NAMES

#: The paper's correct first decision per lift (section "Evaluation"): lock both sides
#: in a squat, the supporting side in an asymmetric stoop.
CORRECT_ACTION: dict[LiftKind, Action] = {
    "squat": Action.LOCK_BOTH,
    "stoop_left": Action.LOCK_LEFT,
    "stoop_right": Action.LOCK_RIGHT,
}

# Labels an experimenter may type; normalised by lower-casing and mapping "-", " " to "_".
_LIFT_ALIASES: dict[str, LiftKind] = {
    "squat": "squat",
    "sq": "squat",
    "stoop_left": "stoop_left",
    "left_stoop": "stoop_left",
    "sl": "stoop_left",
    "stoop_l": "stoop_left",
    "stoop_right": "stoop_right",
    "right_stoop": "stoop_right",
    "sr": "stoop_right",
    "stoop_r": "stoop_right",
}
_TRIAL_ALIASES: dict[str, TrialKind] = {
    "walking": "walking",
    "walk": "walking",
    "w": "walking",
    "stair_walking": "stair_walking",
    "stairs": "stair_walking",
    "stair": "stair_walking",
    "sw": "stair_walking",
    "stairs_walking": "stair_walking",
}
_STAIR_ACTIVITIES = frozenset({"stairs_up", "stairs_down"})


def _norm(label: str) -> str:
    return label.strip().lower().replace("-", "_").replace(" ", "_")


def lift_kind(label: str) -> LiftKind:
    """The lift kind an experimenter's label means ("Stoop left", "SQ", "stoop-right").

    Raises:
        ValueError: the label is not a lifting motion.
    """
    try:
        return _LIFT_ALIASES[_norm(label)]
    except KeyError:
        raise ValueError(
            f"unknown lift label {label!r}; use one of {', '.join(LIFT_KINDS)}"
        ) from None


def trial_kind(label: str) -> TrialKind:
    """The trial kind a label means ("walking", "W", "stairs", "SW").

    Raises:
        ValueError: the label is not a walking or stair-walking trial.
    """
    try:
        return _TRIAL_ALIASES[_norm(label)]
    except KeyError:
        raise ValueError(
            f"unknown trial label {label!r}; use one of {', '.join(TRIAL_KINDS)}"
        ) from None


@dataclass(frozen=True, slots=True)
class Lift:
    """One complete lifting motion: onset to return to standing, `end` inclusive.

    Attributes:
        index: the lift's number within the recording (the simulation's `truth_lift`,
            or the segment's position in time order).
        kind: squat, stoop_left or stoop_right.
        start: tick index of the onset.
        end: tick index of the return to rest (inclusive).
    """

    index: int
    kind: LiftKind
    start: int
    end: int

    def __post_init__(self) -> None:
        if self.kind not in LIFT_KINDS:
            raise ValueError(f"lift kind must be one of {LIFT_KINDS}, got {self.kind!r}")
        if not 0 <= self.start <= self.end:
            raise ValueError(f"need 0 <= start <= end, got {self.start}, {self.end}")

    @property
    def first_half_end(self) -> int:
        """Last tick (inclusive) of the lift's first half: `start + (end - start) // 2`.

        The paper counts recognitions and decisions "during the first half of a
        complete lifting motion" and segmented lifts by their start and end only, so
        the half is taken in time, not up to the peak flexion (which a manual segment
        does not record). For a lift of an even number of ticks this is exactly the
        first half; for an odd number it includes the middle tick. In the simulated
        lifts the peak flexion lies at 40-45 % of the lift, so the first half also
        covers the start of the pause at the bottom.
        """
        return self.start + (self.end - self.start) // 2

    @property
    def first_half(self) -> slice:
        """Ticks of the first half, for indexing columns."""
        return slice(self.start, self.first_half_end + 1)

    @property
    def ticks(self) -> slice:
        """All ticks of the lift, for indexing columns."""
        return slice(self.start, self.end + 1)

    @property
    def correct_action(self) -> Action:
        """The correct first lock decision for this kind of lift."""
        return CORRECT_ACTION[self.kind]


@dataclass(frozen=True, slots=True)
class GaitTrial:
    """A walking or stair-walking trial: ticks `start..end` (inclusive) of a recording,
    where any lock is a false positive."""

    kind: TrialKind
    start: int
    end: int

    def __post_init__(self) -> None:
        if self.kind not in TRIAL_KINDS:
            raise ValueError(f"trial kind must be one of {TRIAL_KINDS}, got {self.kind!r}")
        if not 0 <= self.start <= self.end:
            raise ValueError(f"need 0 <= start <= end, got {self.start}, {self.end}")

    @property
    def ticks(self) -> slice:
        """The trial's ticks, for indexing columns."""
        return slice(self.start, self.end + 1)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, end inclusive) of each run of True."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    d = np.diff(m.astype(np.int8))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    return [(int(s), int(e)) for s, e in zip(starts, ends, strict=True)]


def lifts_from_truth(columns: Columns) -> list[Lift]:
    """The lifts of a simulated recording from its `truth_lift` and `truth_activity`.

    Each lift index `>= 0` is one lift from its first to its last tick; its kind is
    the activity on those ticks. Lifts are returned in time order.

    Raises:
        ValueError: a lift's ticks are not contiguous, or carry an activity that is
            not a lift, or more than one.
    """
    cols = TickData.of(columns)
    lift = cols.int_("truth_lift")
    act = cols.str_("truth_activity")
    out: list[Lift] = []
    for idx in np.unique(lift[lift >= 0]):
        where = np.flatnonzero(lift == idx)
        start, end = int(where[0]), int(where[-1])
        if where.size != end - start + 1:
            raise ValueError(f"lift {idx} is not contiguous in truth_lift")
        kinds = set(act[start : end + 1].tolist())
        if len(kinds) != 1:
            raise ValueError(f"lift {idx} carries activities {sorted(kinds)}")
        kind = lift_kind(kinds.pop())
        out.append(Lift(int(idx), kind, start, end))
    out.sort(key=lambda lf: lf.start)
    return out


def lifts_from_segments(
    segments: Iterable[tuple[int, int, str]],
    n_ticks: int | None = None,
    ignore_labels: Iterable[str] = ("other",),
) -> list[Lift]:
    """Lifts from an experimenter's segments `(start, end, label)`, `end` inclusive.

    Segments are sorted by start and numbered 0, 1, ... in that order (the same
    numbering the simulation uses within a recording). Labels go through
    `lift_kind`, so "SQ" or "Stoop left" are accepted. Segments labelled as in
    `ignore_labels` (by default "other": a stretch the experimenter marked as no
    lift) are left out; any other label that is not a lift, "unlabelled" included,
    is an error, so an unfinished labelling cannot silently shrink the counts.

    Args:
        segments: (start, end, label) per segment.
        n_ticks: the recording's length; when given, segments must lie inside it.
        ignore_labels: labels of segments that are not lifts of the evaluation.

    Raises:
        ValueError: a bad label, `start > end`, a segment outside the recording, or
            two segments that overlap (a tick cannot belong to two lifts).
    """
    skip = {_norm(x) for x in ignore_labels}
    items = sorted(
        (int(s), int(e), lift_kind(lbl)) for s, e, lbl in segments if _norm(lbl) not in skip
    )
    out: list[Lift] = []
    for i, (s, e, kind) in enumerate(items):
        if n_ticks is not None and e >= n_ticks:
            raise ValueError(f"segment {s}..{e} ends beyond the recording ({n_ticks} ticks)")
        if out and s <= out[-1].end:
            raise ValueError(f"segments {out[-1].start}..{out[-1].end} and {s}..{e} overlap")
        out.append(Lift(i, kind, s, e))
    return out


def trials_from_truth(columns: Columns, min_duration_s: float = 5.0) -> list[GaitTrial]:
    """Walking and stair-walking trials of a simulated recording.

    A trial is a maximal run of ticks whose `truth_activity` is a gait activity (walk,
    turn, stairs up, stairs down). A run with any stair tick is a stair-walking trial,
    else a walking trial. Runs shorter than `min_duration_s` are the few strides a
    scripted wearer takes between stations, not a trial of the protocol (the paper
    recorded only its 10 m walk and its stair trial), and are dropped. The standing
    before and after a bout is not part of the trial; for a recording that is one
    trial from end to end use `whole_recording_trial`.
    """
    cols = TickData.of(columns)
    act = cols.str_("truth_activity")
    t = cols.time()
    gait = np.isin(act, np.asarray(GAIT_KINDS))
    out: list[GaitTrial] = []
    for s, e in _runs(gait):
        if t[e] - t[s] < min_duration_s:
            continue
        stairs = bool(np.isin(act[s : e + 1], np.asarray(sorted(_STAIR_ACTIVITIES))).any())
        out.append(GaitTrial("stair_walking" if stairs else "walking", s, e))
    return out


def whole_recording_trial(columns: Columns | int, kind: str) -> GaitTrial:
    """The whole recording as one trial of `kind` ("walking", "stairs", "SW", ...), as
    the paper recorded its walking and stair-walking trials.

    Args:
        columns: the recording's columns, or its number of ticks.
        kind: a label accepted by `trial_kind`.
    """
    n = columns if isinstance(columns, int) else len(TickData.of(columns))
    if n < 1:
        raise ValueError("an empty recording has no trial")
    return GaitTrial(trial_kind(kind), 0, n - 1)

