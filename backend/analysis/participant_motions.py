"""A participant's motions as the personal sets learn from them: where a demonstration's
samples are (for a personal model set), which motions were confirmed and which
posteriors the controller gave unconfirmed use (for a prior set).

Its own module because both kinds of personal set read the same evidence tables the
same way (by the participant's sessions), while the sets themselves are recorded apart
(`personal_model_sets`, `prior_sets`). Refusals are `backend.core.errors`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.analysis import tick_queries
from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db.evidence_tables import LiftSegment, Recording, Trial, TrialSegment
from backend.db.models import Participant, StudySession
from backend.schemas.personalisation import PersonalModelSetIn
from controller.controllers.factory import needs_models
from controller.intent.posteriors import EQUAL_PRIORS
from controller.intent.prior_safety import N_CATEGORIES
from controller.intent.segmentation import segment_lifts
from controller.tick_record import CATEGORY_NAMES, MODEL_NAMES

#: Trial tasks whose completed trials count as confirmed `other` motion.
GAIT_TASKS = ("walking", "stairs")


@dataclass(frozen=True)
class Demo:
    """Where one demonstration's samples are: a run's ticks (ids within a recording,
    or a whole trial) and the sample indices."""

    source: str  # "trial-segment:ID" or "segment:ID"
    label: str
    run_id: int
    first_tick: int | None
    last_tick: int | None
    start: int
    end: int


def known_participant(db: Session, participant_id: int) -> Participant:
    """The participant; `NotFoundError` for an unknown id."""
    row = db.get(Participant, participant_id)
    if row is None:
        raise NotFoundError("participant", participant_id)
    return row


def session_ids(db: Session, participant_id: int) -> list[int]:
    """The ids of the participant's sessions."""
    return list(db.scalars(select(StudySession.id).where(
        StudySession.participant_id == participant_id)))


def demonstrations(db: Session, participant: Participant, body: PersonalModelSetIn
                   ) -> list[Demo]:
    """The demonstrations `body` names (trial segments, the demonstration trial's squat
    and stoop segments, recording segments), each checked to be the participant's."""
    return (_trial_demos(db, participant, body)
            + _recording_demos(db, participant, body.segment_ids))


def _trial_demos(db: Session, participant: Participant, body: PersonalModelSetIn
                 ) -> list[Demo]:
    sessions = set(session_ids(db, participant.id))
    ids = list(dict.fromkeys(body.trial_segment_ids))
    if body.demonstration_trial_id is not None:
        trial = db.get(Trial, body.demonstration_trial_id)
        if trial is None or trial.session_id not in sessions:
            raise InvalidError.at(["body", "demonstration_trial_id"],
                                  f"trial {body.demonstration_trial_id} is not a trial of "
                                  f"participant {participant.code}")
        ids += [s.id for s in db.scalars(select(TrialSegment).where(
            TrialSegment.trial_id == trial.id, TrialSegment.label.in_(MODEL_NAMES))
            .order_by(TrialSegment.start)) if s.id not in ids]
    segs = {s.id: s for s in db.scalars(select(TrialSegment).where(TrialSegment.id.in_(ids)))}
    unknown = [i for i in ids if i not in segs]
    if unknown:
        raise InvalidError.at(["body", "trial_segment_ids"],
                              f"unknown trial segment ids {unknown[:20]}")
    out = []
    for i in ids:
        s = segs[i]
        trial = db.get(Trial, s.trial_id)
        assert trial is not None
        if trial.session_id not in sessions:
            raise InvalidError.at(["body", "trial_segment_ids"], f"trial segment {i} is not "
                                  f"of participant {participant.code}")
        if trial.run_id is None:
            raise InvalidError.at(["body", "trial_segment_ids"], f"trial segment {i}: its "
                                  f"trial {trial.id} has no ticks")
        out.append(Demo(f"trial-segment:{i}", s.label, trial.run_id, None, None, s.start,
                        s.end))
    return out


def _recording_demos(db: Session, participant: Participant, ids: list[int]) -> list[Demo]:
    sessions = set(session_ids(db, participant.id))
    ids = list(dict.fromkeys(ids))
    segs = {s.id: s for s in db.scalars(select(LiftSegment).where(LiftSegment.id.in_(ids)))}
    unknown = [i for i in ids if i not in segs]
    if unknown:
        raise InvalidError.at(["body", "segment_ids"], f"unknown segment ids {unknown[:20]}")
    out = []
    for i in ids:
        s = segs[i]
        rec = db.get(Recording, s.recording_id)
        if rec is None or rec.session_id not in sessions or rec.run_id is None:
            raise InvalidError.at(["body", "segment_ids"], f"segment {i} is not in a "
                                  f"recording of participant {participant.code}")
        out.append(Demo(f"segment:{i}", s.label, rec.run_id, rec.first_tick_id,
                        rec.last_tick_id, s.start, s.end))
    return out


def confirmed_motions(db: Session, participant: Participant, include_recordings: bool,
                      gait_trials_as_other: bool) -> list[tuple[str, str]]:
    """(source id, category) of the participant's confirmed motions, oldest first:
    labelled trial segments, labelled recording segments and completed gait trials.

    A source id names the motion, not the row that holds it: a lift is its trial (or
    recording) and its first and last sample (`trial:12:300-399`). Saving a trial's
    segments replaces their rows; the lifts keep their ids, so a later prior set
    neither skips them nor counts them again."""
    sessions = session_ids(db, participant.id)
    timed: list[tuple[float, str, str]] = []
    trials = list(db.scalars(select(Trial).where(Trial.session_id.in_(sessions or [-1]),
                                                 Trial.started_at.is_not(None))))
    for trial in trials:
        assert trial.started_at is not None
        t0 = trial.started_at.timestamp()
        for s in db.scalars(select(TrialSegment).where(TrialSegment.trial_id == trial.id)):
            if s.label in CATEGORY_NAMES:
                timed.append((t0 + s.peak / 100.0, f"trial:{trial.id}:{s.start}-{s.end}",
                              s.label))
        if gait_trials_as_other and trial.task in GAIT_TASKS and trial.status == "completed":
            timed.append((t0, f"gait-trial:{trial.id}", "other"))
    if include_recordings:
        for rec in db.scalars(select(Recording).where(Recording.session_id.in_(sessions or [-1]))):
            t0 = rec.started_at.timestamp()
            for ls in db.scalars(select(LiftSegment).where(LiftSegment.recording_id == rec.id)):
                if ls.label in CATEGORY_NAMES:
                    timed.append((t0 + ls.peak / 100.0,
                                  f"recording:{rec.id}:{ls.start}-{ls.end}", ls.label))
    timed.sort()
    return list(dict((src, lab) for _, src, lab in timed).items())


def _trial_priors(trial: Trial) -> tuple[float, ...]:
    """The priors a trial ran with (its snapshot's; equal ones if it names none).

    Raises:
        ConflictError: the snapshot's priors are not 4 positive finite values summing
            to 1 (the EM estimate divides by them), naming the trial."""
    snap = (trial.config_snapshot or {}).get("settings") or {}
    pr = snap.get("priors") if isinstance(snap, dict) else None
    if pr is None:
        return tuple(EQUAL_PRIORS)
    ok = isinstance(pr, list) and len(pr) == N_CATEGORIES and all(
        isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and x > 0
        for x in pr) and abs(sum(pr) - 1.0) <= 1e-6
    if not ok:
        raise ConflictError("method", f"trial {trial.id} ran with priors {pr!r} in its "
                            "configuration snapshot; label-shift-em needs 4 positive "
                            "values summing to 1 for every trial it learns from")
    return tuple(float(x) for x in pr)


def unconfirmed_posteriors(db: Session, participant: Participant,
                           window_s: float) -> tuple[np.ndarray, tuple[float, ...], list[str]]:
    """One posterior per motion of the participant's completed UMC and E-UMC trials
    (every segmented lift at its peak, and one per `window_s` of ticks outside lifts, at
    the window's middle), the priors those trials ran with, and the source ids.

    Raises:
        InvalidError: no such trial, or trials that ran with different priors (one
            training prior is what the EM estimate needs)."""
    sessions = session_ids(db, participant.id)
    trials = [t for t in db.scalars(select(Trial).where(
        Trial.session_id.in_(sessions or [-1]), Trial.status == "completed")
        .order_by(Trial.started_at)) if needs_models(t.controller) and t.run_id is not None]
    if not trials:
        raise InvalidError.at(["body", "method"], "label-shift-em learns from completed "
                              f"UMC or E-UMC trials; participant {participant.code} has none")
    train = {_trial_priors(t) for t in trials}
    if len(train) > 1:
        raise InvalidError.at(["body", "method"], "the participant's trials ran with "
                              f"different priors {sorted(train)}; the EM estimate needs one")
    posts: list[np.ndarray] = []
    sources: list[str] = []
    fields = ("t", "q_left", "q_right", "controller_ran", "post_squat", "post_stoop_left",
              "post_stoop_right", "post_other")
    for trial in trials:
        assert trial.run_id is not None
        # The session's connection: one per request (tick_queries' docstring).
        cols = tick_queries.columns(db.connection(), trial.run_id, fields=fields)
        post = np.column_stack([cols[f] for f in fields[4:]]).astype(np.float64)
        ok = np.asarray(cols["controller_ran"], dtype=bool) & np.isfinite(post).all(axis=1)
        evaluated = np.flatnonzero(ok)
        if evaluated.size == 0:
            continue
        t = np.asarray(cols["t"], dtype=np.float64)
        q = np.column_stack([cols["q_left"], cols["q_right"]]).astype(np.float64)
        covered = np.zeros(len(t), dtype=bool)
        finite = np.isfinite(q).all(axis=1) & np.isfinite(t)
        lifts = segment_lifts(t[finite], q[finite]) if finite.sum() > 10 and \
            bool(np.all(np.diff(t[finite]) > 0)) else []
        index = np.flatnonzero(finite)
        for i, lift in enumerate(lifts):
            a, p, b = index[lift.start], index[lift.peak], index[lift.end]
            covered[a:b + 1] = True
            k = evaluated[np.argmin(np.abs(evaluated - p))]
            posts.append(post[k])
            sources.append(f"trial:{trial.id}:lift={i}")
        free = evaluated[~covered[evaluated]]
        if free.size:
            bins = np.floor((t[free] - t[free][0]) / window_s).astype(int)
            for b in np.unique(bins):
                members = free[bins == b]
                k = members[len(members) // 2]
                posts.append(post[k])
                sources.append(f"trial:{trial.id}:window={int(b)}")
    if not posts:
        raise InvalidError.at(["body", "method"], "the participant's UMC and E-UMC trials "
                              "have no evaluated ticks")
    arr = np.asarray(posts, dtype=np.float64)
    arr = arr / arr.sum(axis=1, keepdims=True)
    return arr, train.pop(), sources
