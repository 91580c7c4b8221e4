"""A wearer's progress over long-use sessions: the stored long-use trials, their ground
truth, and the learning curves of `controller.evaluation.learning_curve`.

Ground truth of a long-use trial:

- **simulation**: the simulated wearer's truth columns give every lift and every
  walking or stair bout (`backend.analysis.results.ground_truth`); every lift is
  confirmed; lifts cut by the trial's start or end count in lifts per hour only.
- **a real study** (no truth columns): lifts are the trial's lift segments
  (`/api/trials/{id}/segment` proposes them from the hip angles, the experimenter
  labels them). A segment labelled with a lift is a **confirmed** lift and is scored;
  one still `unlabelled` is an **unconfirmed** lift: it counts in lifts per hour and in
  nothing else (its correct action is unknown); one labelled `other` is no lift. Walking
  and stair bouts come from the experimenter's **markers**: a marker whose label is a
  gait label (`walking`, `walk`, `stairs`, `stair walking`, ...) starts a bout of that
  kind, which runs until the trial's next marker (any label: "standing", "lifting",
  "end") or the trial's end. Without such markers a real trial has no gait hours, and
  its false-positive rates are left empty rather than zero.

Only completed and interrupted long-use trials count (an interrupted one holds the
ticks up to its worker's end); aborted, planned and running ones are listed as skipped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.analysis.markers import trial_markers
from backend.analysis.results import ground_truth, trial_segments
from backend.analysis.tick_queries import run_ticks
from backend.core.errors import ConflictError, NotFoundError
from backend.db.evidence_tables import Trial
from backend.db.models import Participant, StudySession
from backend.schemas.wearers import LONG_USE_TASK, WearerProgressOut
from controller.controllers import registry
from controller.device.base import SAMPLE_PERIOD_S
from controller.evaluation.columns import TickData
from controller.evaluation.ground_truth import NO_TRUTH
from controller.evaluation.lifts import GaitTrial, Lift, lifts_from_segments, trial_kind
from controller.evaluation.metrics import FalsePositives, LiftOutcome
from controller.evaluation.study import evaluate_recording

#: Long-use trials in these states count; others are skipped.
COUNTED = ("completed", "interrupted")


@dataclass(frozen=True)
class LongUseTruth:
    """Lifts and gait bouts of one long-use trial and where they came from."""

    source: str
    lifts: tuple[Lift, ...] = ()
    gait: tuple[GaitTrial, ...] = ()
    unconfirmed: int = 0
    incomplete: int = 0
    note: str = ""


def marker_bouts(t: np.ndarray, marks: list[tuple[float, str]]) -> list[GaitTrial]:
    """Walking and stair bouts from markers `(device time, label)` on ticks at times `t`:
    a gait label starts a bout, the next marker (or the last tick) ends it."""
    n = int(t.size)
    if n == 0:
        return []
    ordered = sorted(marks)
    out: list[GaitTrial] = []
    for i, (at, label) in enumerate(ordered):
        try:
            kind = trial_kind(label)
        except ValueError:
            continue
        start = int(np.searchsorted(t, at, side="left"))
        end = (int(np.searchsorted(t, ordered[i + 1][0], side="left")) - 1
               if i + 1 < len(ordered) else n - 1)
        end = min(end, n - 1)
        if start < n and end > start:
            out.append(GaitTrial(kind, start, end))
    return out


def long_use_truth(cols: TickData, segments: list[tuple[int, int, str]],
                   marks: list[tuple[float, str]]) -> LongUseTruth:
    """The ground truth of one long-use trial (rules in the module docstring)."""
    n = len(cols)
    if n == 0:
        return LongUseTruth("none", note="no stored ticks")
    sim = ground_truth(cols, LONG_USE_TASK)
    if sim.source == "simulation":
        return LongUseTruth("simulation", sim.lifts, sim.gait, 0, sim.incomplete_lifts,
                            sim.note)
    gait = tuple(marker_bouts(cols.time(), marks))
    unconfirmed = sum(1 for s in segments if s[2] == "unlabelled")
    try:
        lifts = tuple(lifts_from_segments(segments, n_ticks=n,
                                          ignore_labels=("other", "unlabelled")))
    except ValueError as exc:
        return LongUseTruth("none", (), gait, note=f"the lift segments cannot be used: {exc}")
    source = "segments" if segments or gait else "none"
    return LongUseTruth(source, lifts, gait, unconfirmed, 0,
                        f"{len(lifts)} confirmed and {unconfirmed} unconfirmed lifts from "
                        f"the segments, {len(gait)} gait bouts from the markers")


@dataclass
class _Session:
    sess: StudySession
    trials: list[Trial] = field(default_factory=list)
    truths: list[str] = field(default_factory=list)
    outcomes: list[LiftOutcome] = field(default_factory=list)
    fps: list[FalsePositives] = field(default_factory=list)
    hours: float = 0.0
    unconfirmed: int = 0
    incomplete: int = 0


def wearer_progress(db: Session, participant_id: int,
                    controller: str | None = None) -> WearerProgressOut:
    """The participant's long-use sessions in time order (those with a counted trial,
    of `controller` if given), each session's counts, and the learning curves.

    Ticks are read on the session's own connection: one request, one pooled
    connection (a second one per request starves the pool under load)."""
    # The learning curves' statistics (SciPy) on first use: every server start imports
    # this module, and SciPy costs it ~0.7 s of CPU.
    from controller.evaluation.learning_curve import SessionUse, learning_curves, session_use

    part = db.get(Participant, participant_id)
    if part is None:
        raise NotFoundError("participant", participant_id)
    if part.withdrawn_at is not None:
        raise ConflictError("participant", f"participant {part.code} withdrew; their data "
                            "are left out of every result")
    sessions = list(db.scalars(select(StudySession).where(
        StudySession.participant_id == participant_id, StudySession.kind == "long_use")
        .order_by(StudySession.started_at, StudySession.id)))
    skipped: list[dict[str, str | int]] = []
    gathered: list[_Session] = []
    for sess in sessions:
        acc = _Session(sess)
        for trial in db.scalars(select(Trial).where(
                Trial.session_id == sess.id, Trial.task == LONG_USE_TASK)
                .order_by(Trial.planned_order, Trial.id)):
            if controller is not None and trial.controller != controller:
                continue
            if trial.status not in COUNTED or trial.run_id is None:
                skipped.append({"trial_id": trial.id, "session_id": sess.id,
                                "reason": f"trial is {trial.status}"})
                continue
            cols = run_ticks(db.connection(), trial.run_id)
            marks = [(m.t, m.label) for m in trial_markers(db, trial.id)
                     if m.t is not None and m.source != "system"]
            truth = long_use_truth(cols, trial_segments(db, trial.id), marks)
            ev = evaluate_recording(cols, part.code, trial.controller, truth.lifts,
                                    truth.gait, recording=f"trial-{trial.id}")
            acc.trials.append(trial)
            acc.truths.append(truth.source)
            acc.outcomes.extend(ev.lifts)
            acc.fps.extend(ev.false_positives)
            acc.hours += len(cols) * SAMPLE_PERIOD_S / 3600.0
            acc.unconfirmed += truth.unconfirmed
            acc.incomplete += truth.incomplete
        if acc.trials:
            gathered.append(acc)
    uses: list[SessionUse] = [session_use(a.hours, a.outcomes, a.fps, a.unconfirmed,
                                          a.incomplete) for a in gathered]
    curves = learning_curves(uses)
    notes = ["lifts per hour counts every lift; recognition, lock rate and time to lock "
             "only confirmed lifts (simulation truth, or segments labelled with a lift)"]
    if any("segments" in a.truths or NO_TRUTH in a.truths for a in gathered):
        notes.append("false positives per hour of walking and stairs need gait markers "
                     "(a marker labelled walking or stairs starts a bout, the next marker "
                     "ends it)")
    if len(uses) < 3:
        notes.append("a trend's interval needs at least three sessions")
    return WearerProgressOut.model_validate({
        "participant_id": part.id, "participant": part.code, "controller": controller,
        "sessions": [{
            "number": i, "session_id": a.sess.id, "started_at": a.sess.started_at,
            "controllers": sorted({t.controller for t in a.trials}),
            "trial_ids": [t.id for t in a.trials], "truth": a.truths,
            "hours": _finite(u.hours), "lifts": u.lifts, "confirmed_lifts": u.confirmed,
            "unconfirmed_lifts": a.unconfirmed, "incomplete_lifts": a.incomplete,
            "recognised": u.recognised, "correct_locks": u.correct_locks,
            "walking_hours": _finite(u.walking_hours), "walking_fp": u.walking_fp,
            "stairs_hours": _finite(u.stairs_hours), "stairs_fp": u.stairs_fp,
        } for i, (a, u) in enumerate(zip(gathered, uses, strict=True), start=1)],
        "curves": [c.to_dict() for c in curves.values()],
        "skipped": skipped, "notes": notes,
        "long_use_controllers": [r.name for r in registry.planned()],
    })


def _finite(v: float) -> float:
    return float(v) if math.isfinite(v) else 0.0
