"""The paper's evaluation metrics (section "Evaluation"), per lift and per trial.

The paper's rules, and the choices this module makes where the paper leaves room:

- **First half** of a lift: ticks `start .. start + (end - start) // 2` (see
  `Lift.first_half_end`): half in time, because the paper's manual segments record
  start and end only.
- **Recognition**: a lift is recognised if the posterior of the correct model,
  `post_<kind>`, is `>= 0.5` at some tick of the first half (the paper:
  `P(model|obs) >= 0.5`). Ticks where the posterior was not computed (NaN) do not
  count. A controller without intent estimation (the PEC) has no recognition:
  `recognised` is None, not False. Whether a controller estimates intent is known
  from its name where possible (`evaluate_recording`), else inferred from the data:
  any posterior computed anywhere in the recording.
- **Lock decision**: a tick at which the high-level controller ran
  (`controller_ran`) and decided a locking action (`action` 2, 3 or 4). The `action`
  column holds the last decision between runs, so ticks where the controller did not
  run are not decisions. A 100 Hz "no lock" (the idle E-UMC) is not a lock decision.
- **Decision outcome** (`LiftOutcome.decision`, the paper's counting rule). The paper
  (section "Evaluation"): "the number of correct decisions, taken in the first half of
  a lifting motion, was counted", "a correct decision was to lock both sides during a
  squat motion, lock left side during stoop left motions and lock right side during
  stoop right motions", and "the first decision during an asymmetric stoop motion
  should always be to engage the supporting side". Its discussion adds that in squats
  the UMC "initially only locked the right support mechanism" and then "locked the
  left support mechanism as well", while its table still counts those squats as
  correct. So:
  - squat: **correct** if both sides have been commanded to lock within the first
    half, in one decision (lock both) or in two (one side, then the other); **wrong**
    if only one side was; **missed** if none was;
  - stoop: **correct** if the first lock decision in the first half is the supporting
    side alone (lock left in a stoop left); **wrong** if it is another locking action;
    **missed** if there is none.
- **First decision** (`LiftOutcome.first_decision`, the stricter reading): the first
  lock decision in the first half is the lift's correct action, else wrong; none is
  missed. For stoops it equals the paper's rule; for squats it counts a squat whose
  first lock was one-sided as wrong even when the other side followed in time
  (`LiftOutcome.first_lock_one_sided`), which is the delayed locking the paper's
  discussion blames for asymmetric squat torques.
  A lock decided after the first half is missed under both readings.
- **Peak torque**: the maximum of `torque_left` and of `torque_right` over the whole
  lift (the actuator model applied to the measured spring deflection; see
  `controller.evaluation.torques` to recompute it), NaN ticks ignored.
- **Onset to lock** (not in the paper): time from the lift's first tick to the first
  tick of the lift at which the held command (`lock_left`/`lock_right`, after the
  0.3 s hold) is on for either side ("first lock"), and to the moment the correct
  side is held ("correct lock": for a squat the later of the first left and the first
  right held tick, i.e. when both sides have been engaged; for a stoop the first held
  tick of the supporting side). A command already held at the lift's first tick gives
  0. NaN if it never happens within the lift.
- **False positives**: see `count_false_positives`.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from controller.evaluation.columns import BoolArray, Columns, FloatArray, TickData
from controller.evaluation.lifts import GaitTrial, Lift
from controller.tick_record import Action

#: The paper's recognition threshold on the correct model's posterior.
RECOGNITION_THRESHOLD = 0.5
_LOCK_ACTIONS = np.array([int(Action.LOCK_BOTH), int(Action.LOCK_RIGHT), int(Action.LOCK_LEFT)])
#: The sides each locking action commands.
ACTION_SIDES: dict[Action, str] = {Action.LOCK_BOTH: "LR", Action.LOCK_LEFT: "L",
                                   Action.LOCK_RIGHT: "R"}


class DecisionOutcome(enum.StrEnum):
    """The outcome of a lift's lock decisions in its first half (rules in the module
    docstring)."""

    CORRECT = "correct"
    WRONG = "wrong"
    MISSED = "missed"


@dataclass(frozen=True, slots=True)
class LiftOutcome:
    """Every per-lift metric of one lift.

    Attributes:
        lift: the lift.
        recognised: the correct posterior reached 0.5 in the first half; None if the
            recording has no posteriors (a controller without intent estimation).
        peak_posterior: the largest correct-model posterior in the first half (NaN if
            none was computed there).
        recognised_s: time from onset to the first tick of the first half with the
            correct posterior >= 0.5 (NaN if not recognised).
        decision: correct, wrong or missed by the paper's counting rule.
        first_decision: correct, wrong or missed by the first lock decision alone.
        first_lock_one_sided: the first lock decision in the first half locked one side
            only (lock left or lock right); False if there was none.
        sides_commanded: which sides ("L", "R") any lock decision of the first half
            commanded, e.g. "LR" or "" (none).
        first_action: the first lock decision in the first half, None if missed.
        first_decision_s: its time from onset (NaN if missed).
        peak_torque_left: peak left exoskeleton torque over the lift (Nm).
        peak_torque_right: peak right exoskeleton torque over the lift (Nm).
        first_lock_s: onset to the first held command on either side (NaN if none).
        correct_lock_s: onset to the correct side(s) held (NaN if never).
    """

    lift: Lift
    recognised: bool | None
    peak_posterior: float
    recognised_s: float
    decision: DecisionOutcome
    first_decision: DecisionOutcome
    first_lock_one_sided: bool
    sides_commanded: str
    first_action: Action | None
    first_decision_s: float
    peak_torque_left: float
    peak_torque_right: float
    first_lock_s: float
    correct_lock_s: float


def _first(mask: BoolArray) -> int | None:
    hits = np.flatnonzero(mask)
    return int(hits[0]) if hits.size else None


def _nanmax(a: FloatArray) -> float:
    finite = a[np.isfinite(a)]
    return float(finite.max()) if finite.size else math.nan


def lock_decisions(columns: Columns) -> BoolArray:
    """Per tick: the controller ran and decided a locking action (2, 3 or 4)."""
    cols = TickData.of(columns)
    return cols.bool_("controller_ran") & np.isin(cols.int_("action"), _LOCK_ACTIONS)


def estimates_intent(columns: Columns) -> bool:
    """True if any model posterior was computed anywhere in the recording."""
    cols = TickData.of(columns)
    names = [f"post_{k}" for k in ("squat", "stoop_left", "stoop_right")]
    return any(n in cols and bool(np.isfinite(cols.float_(n)).any()) for n in names)


def _torque(cols: TickData, side: str, lift: Lift) -> float:
    name = f"torque_{side}"
    return _nanmax(cols.float_(name)[lift.ticks]) if name in cols else math.nan


def _first_held_s(held: BoolArray, t: FloatArray, lift: Lift) -> float:
    k = _first(held[lift.ticks])
    return math.nan if k is None else float(t[lift.start + k] - t[lift.start])


def evaluate_lift(
    columns: Columns, lift: Lift, with_intent: bool | None = None
) -> LiftOutcome:
    """All per-lift metrics of `lift` (rules in the module docstring).

    Args:
        columns: the recording's ticks; needs `controller_ran`, `action`, `lock_left`,
            `lock_right`; uses `post_<kind>`, `torque_*` and `t` when present.
        lift: the lift, with indices into `columns`.
        with_intent: whether the controller estimates intent; None infers it from the
            columns (`estimates_intent`). Pass it when evaluating one lift of a
            recording out of context.
    """
    cols = TickData.of(columns)
    if lift.end >= len(cols):
        raise ValueError(f"lift {lift.index} ends at tick {lift.end}, beyond {len(cols)} ticks")
    t = cols.time()
    half = lift.first_half
    intent = estimates_intent(cols) if with_intent is None else with_intent

    post_name = f"post_{lift.kind}"
    recognised: bool | None = None
    peak_post = math.nan
    recognised_s = math.nan
    if intent:
        post = cols.float_(post_name)[half] if post_name in cols else np.full(0, math.nan)
        peak_post = _nanmax(post)
        k = _first(post >= RECOGNITION_THRESHOLD)  # NaN compares False
        recognised = k is not None
        if k is not None:
            recognised_s = float(t[lift.start + k] - t[lift.start])

    # `lock_decisions` on the first half only: over the whole recording, once per lift,
    # it was a tenth of a virtual cohort's cost.
    actions = cols.int_("action")[half]
    decided = cols.bool_("controller_ran")[half] & np.isin(actions, _LOCK_ACTIONS)
    k = _first(decided)
    sides = ""
    if k is None:
        first, first_action, first_s = DecisionOutcome.MISSED, None, math.nan
    else:
        first_action = Action(int(actions[k]))
        first_s = float(t[lift.start + k] - t[lift.start])
        first = (DecisionOutcome.CORRECT if first_action == lift.correct_action
                 else DecisionOutcome.WRONG)
        commanded = {s for a in np.unique(actions[decided]) for s in ACTION_SIDES[Action(int(a))]}
        sides = "".join(s for s in "LR" if s in commanded)
    if lift.kind == "squat":
        outcome = (DecisionOutcome.MISSED if not sides else
                   DecisionOutcome.CORRECT if sides == "LR" else DecisionOutcome.WRONG)
    else:
        outcome = first

    left, right = cols.bool_("lock_left"), cols.bool_("lock_right")
    first_lock = _first_held_s(left | right, t, lift)
    if lift.kind == "squat":
        fl, fr = _first_held_s(left, t, lift), _first_held_s(right, t, lift)
        correct_lock = math.nan if math.isnan(fl) or math.isnan(fr) else max(fl, fr)
    else:
        correct_lock = _first_held_s(left if lift.kind == "stoop_left" else right, t, lift)

    return LiftOutcome(
        lift=lift,
        recognised=recognised,
        peak_posterior=peak_post,
        recognised_s=recognised_s,
        decision=outcome,
        first_decision=first,
        first_lock_one_sided=first_action in (Action.LOCK_LEFT, Action.LOCK_RIGHT),
        sides_commanded=sides,
        first_action=first_action,
        first_decision_s=first_s,
        peak_torque_left=_torque(cols, "left", lift),
        peak_torque_right=_torque(cols, "right", lift),
        first_lock_s=first_lock,
        correct_lock_s=correct_lock,
    )


def evaluate_lifts(
    columns: Columns, lifts: Sequence[Lift], with_intent: bool | None = None
) -> list[LiftOutcome]:
    """`evaluate_lift` for every lift of one recording, in the given order.

    `with_intent` as in `evaluate_lift`; None infers it once from the whole recording.
    """
    cols = TickData.of(columns)
    intent = estimates_intent(cols) if with_intent is None else with_intent
    return [evaluate_lift(cols, lf, intent) for lf in lifts]


@dataclass(frozen=True, slots=True)
class FalsePositives:
    """Lock commands during one walking or stair-walking trial.

    Attributes:
        trial: the trial.
        signals: **the paper's count**: rising edges of the held command sent to the
            device, either side: each time the low-level controller goes from no side
            held to at least one side held. One such edge is one lock the wearer
            could feel, however many controller evaluations asked for it (the 0.3 s
            hold merges requests less than 0.3 s apart).
        edges_left: rising edges of the held left command.
        edges_right: rising edges of the held right command.
        decisions: controller evaluations in the trial that decided a locking action
            (the alternative definition: "every controller evaluation deciding a
            lock"; at 100 Hz one episode gives tens of these).
        lock_ticks: ticks with a held command on either side.
        duration_s: the trial's duration.
    """

    trial: GaitTrial
    signals: int
    edges_left: int
    edges_right: int
    decisions: int
    lock_ticks: int
    duration_s: float


def _rising(held: BoolArray) -> BoolArray:
    """True at each tick where `held` turns on; on at tick 0 counts as a rise."""
    prev = np.concatenate([[False], held[:-1]])
    return held & ~prev


def count_false_positives(columns: Columns, trials: Sequence[GaitTrial]) -> list[FalsePositives]:
    """False positive lock commands per gait trial (the paper's "False positives").

    Every lock command sent during a walking or stair-walking trial is a false
    positive. The paper's table counts "false positive lock signals" (at most 20 in a
    stair trial of 22 steps, 0 for the PEC, whose evaluations run at 100 Hz), which
    fits counting lock episodes sent to the low-level controller rather than
    evaluations; `signals` is that count, the other definitions are kept alongside
    (see `FalsePositives`). Edges are found over the whole recording, so a command
    that was already held when the trial started is not counted as a new one.
    """
    cols = TickData.of(columns)
    n = len(cols)
    left, right = cols.bool_("lock_left"), cols.bool_("lock_right")
    either = left | right
    rise_any, rise_l, rise_r = _rising(either), _rising(left), _rising(right)
    decided = lock_decisions(cols)
    t = cols.time()
    out: list[FalsePositives] = []
    for tr in trials:
        if tr.end >= n:
            raise ValueError(f"trial {tr.start}..{tr.end} ends beyond the recording ({n} ticks)")
        s = tr.ticks
        out.append(
            FalsePositives(
                trial=tr,
                signals=int(rise_any[s].sum()),
                edges_left=int(rise_l[s].sum()),
                edges_right=int(rise_r[s].sum()),
                decisions=int(decided[s].sum()),
                lock_ticks=int(either[s].sum()),
                duration_s=float(t[tr.end] - t[tr.start]),
            )
        )
    return out


LockTiming = Literal["first", "correct"]


@dataclass(frozen=True, slots=True)
class OnsetToLockSummary:
    """Distribution of onset-to-lock times over a set of lifts.

    Attributes:
        n_lifts: lifts considered.
        n_locked: lifts where the lock happened (the others are excluded from the
            statistics, not counted as infinite).
        median_s, q25_s, q75_s: median and quartiles (linear interpolation) in
            seconds; NaN when no lift locked.
    """

    n_lifts: int
    n_locked: int
    median_s: float
    q25_s: float
    q75_s: float

    @property
    def iqr_s(self) -> float:
        """Inter-quartile range (s)."""
        return self.q75_s - self.q25_s


def onset_to_lock_times(outcomes: Sequence[LiftOutcome], which: LockTiming = "first") -> FloatArray:
    """Per lift, onset to the first lock (`which="first"`) or to the correct side(s)
    held (`which="correct"`), in seconds, NaN where it never happened."""
    if which not in ("first", "correct"):
        raise ValueError(f"which must be 'first' or 'correct', got {which!r}")
    attr = "first_lock_s" if which == "first" else "correct_lock_s"
    return np.asarray([getattr(o, attr) for o in outcomes], dtype=np.float64)


def summarise_onset_to_lock(
    outcomes: Sequence[LiftOutcome], which: LockTiming = "first"
) -> OnsetToLockSummary:
    """Median and IQR of `onset_to_lock_times` over the lifts that locked."""
    x = onset_to_lock_times(outcomes, which)
    ok = x[np.isfinite(x)]
    if ok.size == 0:
        return OnsetToLockSummary(len(x), 0, math.nan, math.nan, math.nan)
    q25, med, q75 = np.percentile(ok, [25.0, 50.0, 75.0])
    return OnsetToLockSummary(len(x), int(ok.size), float(med), float(q25), float(q75))
