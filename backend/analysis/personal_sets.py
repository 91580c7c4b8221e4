"""Personal model sets and prior sets of a participant: checked, recorded with their
provenance, then fitted (a background job, like a population model set) or learned.

The service behind `backend/api/routes/personalisation.py`; refusals are
`backend.core.errors`. The pure methods are `controller.intent.personal_models`,
`learned_priors`, `label_shift` and `prior_safety`: every prior set stored here went
through `PriorBounds.project` (learned) or `PriorBounds.violation` (imported) against
the utility set it names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import Engine, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker

from backend.analysis import tick_queries
from backend.analysis.fitting import _failure, _set_row
from backend.analysis.jobs import JobRunner
from backend.core.errors import ConflictError, InvalidError
from backend.db import audit
from backend.db.evidence_tables import (
    LiftSegment,
    ModelSetRecord,
    Recording,
    Trial,
    TrialSegment,
    UtilitySetRecord,
)
from backend.db.models import Participant, StudySession, User
from backend.db.personalisation import PriorSetRecord
from backend.schemas.personalisation import PersonalModelSetIn, PersonalModelSetOut, PriorSetIn
from controller.controllers.factory import needs_models
from controller.intent.label_shift import learn_from_unconfirmed
from controller.intent.learned_priors import LearnedPriors, learn_from_confirmed
from controller.intent.motion_model import ModelSet
from controller.intent.personal_models import adapt_model_set, fit_participant_model_set
from controller.intent.posteriors import EQUAL_PRIORS
from controller.intent.prior_safety import N_CATEGORIES, PriorBounds
from controller.intent.segmentation import segment_lifts
from controller.tick_record import CATEGORY_NAMES, MODEL_NAMES

GAIT_TASKS = ("walking", "stairs")


@dataclass(frozen=True)
class _Demo:
    """Where one demonstration's samples are: a run's ticks (ids within a recording,
    or a whole trial) and the sample indices."""

    source: str  # "trial-segment:ID" or "segment:ID"
    label: str
    run_id: int
    first_tick: int | None
    last_tick: int | None
    start: int
    end: int


def _participant_sessions(db: Session, participant_id: int) -> list[int]:
    return list(db.scalars(select(StudySession.id).where(
        StudySession.participant_id == participant_id)))


def _trial_demos(db: Session, participant: Participant, body: PersonalModelSetIn
                 ) -> list[_Demo]:
    sessions = set(_participant_sessions(db, participant.id))
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
        out.append(_Demo(f"trial-segment:{i}", s.label, trial.run_id, None, None, s.start,
                         s.end))
    return out


def _recording_demos(db: Session, participant: Participant, ids: list[int]) -> list[_Demo]:
    sessions = set(_participant_sessions(db, participant.id))
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
        out.append(_Demo(f"segment:{i}", s.label, rec.run_id, rec.first_tick_id,
                         rec.last_tick_id, s.start, s.end))
    return out


def _population_set(db: Session, ref: int | None, study_id: int) -> ModelSetRecord | None:
    if ref is None:
        return None
    row = db.get(ModelSetRecord, ref)
    loc: list[str | int] = ["body", "population_model_set_id"]
    if row is None:
        raise InvalidError.at(loc, f"model set {ref} does not exist")
    if row.study_id != study_id or row.kind != "population":
        raise InvalidError.at(loc, f"model set {ref} is not a population model set of this "
                              "study")
    if row.status != "ready" or row.document is None:
        raise ConflictError("population_model_set_id", f"model set {ref} is {row.status}, "
                            "not ready")
    return row


def fit_personal_set(db: Session, engine: Engine, sessions: sessionmaker[Session],
                     jobs: JobRunner, user: User, participant: Participant,
                     body: PersonalModelSetIn) -> PersonalModelSetOut:
    """Check the demonstrations (this participant's, labelled squat or stoop) and the
    population set, record the personal set as `fitting` with its provenance and queue
    the fit; the answer carries the job id."""
    demos = _trial_demos(db, participant, body) + _recording_demos(db, participant,
                                                                   body.segment_ids)
    bad = [d.source for d in demos if d.label not in MODEL_NAMES]
    if bad:
        raise InvalidError.at(["body"], f"demonstrations {bad[:20]} are not labelled as "
                              f"{', '.join(MODEL_NAMES)}")
    counts = {m: sum(d.label == m for d in demos) for m in MODEL_NAMES}
    if not demos:
        raise InvalidError.at(["body", "demonstration_trial_id"], "the demonstration block "
                              "has no segments labelled squat or stoop: mark them first")
    if body.method == "participant-only":
        short = {m: c for m, c in counts.items() if c < body.min_per_motion}
        if short:
            raise InvalidError.at(["body"], "a participant-only model set needs at least "
                                  f"{body.min_per_motion} demonstrations of each motion; have "
                                  + ", ".join(f"{m}: {c}" for m, c in short.items()))
    population = _population_set(db, body.population_model_set_id, participant.study_id)
    params: dict[str, Any] = {
        "method": body.method, "counts": counts, "demonstrations": [d.source for d in demos],
        "demonstration_trial_id": body.demonstration_trial_id,
        "population_model_set_id": body.population_model_set_id,
        "population_version": None if population is None or population.document is None
        else population.document.get("version")}
    if body.method == "map":
        params["tau"] = body.tau
    else:
        params.update(min_per_motion=body.min_per_motion, latent_dim=body.latent_dim)
    row = ModelSetRecord(study_id=participant.study_id, name=body.name, status="fitting",
                         params=params, created_by=user.id, kind="personal",
                         segment_ids=[int(d.source.split(":")[1]) for d in demos
                                      if d.source.startswith("segment:")],
                         method="map" if body.method == "map" else "ppca",
                         participant_id=participant.id,
                         base_model_set_id=body.population_model_set_id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "model_set", row.id,
                 {"name": body.name, "kind": "personal", "participant_id": participant.id,
                  **params})
    db.commit()
    ms_id, code, study_id = row.id, participant.code, participant.study_id
    population_doc = population.document if population is not None else None

    def work(progress: Any) -> str:
        segs: dict[str, list[np.ndarray]] = {m: [] for m in MODEL_NAMES}
        ids: dict[str, list[str]] = {m: [] for m in MODEL_NAMES}
        cache: dict[tuple[int, int | None, int | None], np.ndarray] = {}
        for k, d in enumerate(demos):
            key = (d.run_id, d.first_tick, d.last_tick)
            if key not in cache:
                cols = tick_queries.columns(engine, d.run_id, d.first_tick, d.last_tick,
                                            fields=("q_left", "q_right"))
                cache[key] = np.column_stack([cols["q_left"], cols["q_right"]])
            q = cache[key]
            if d.end >= len(q):
                raise ValueError(f"{d.source} ends at sample {d.end}, after the "
                                 f"{len(q)} stored ticks")
            seg = q[d.start:d.end + 1]
            if np.isnan(seg).any():
                raise ValueError(f"{d.source} contains bad samples; edit its edges")
            segs[d.label].append(seg)
            ids[d.label].append(d.source)
            progress(0.8 * (k + 1) / len(demos))
        version = f"study-{study_id}-personal-{ms_id}"
        if body.method == "map":
            assert population_doc is not None
            mset = adapt_model_set(ModelSet.from_json(population_doc), segs, tau=body.tau,
                                   demo_ids=ids, participant=code, version=version)
        else:
            mset = fit_participant_model_set(segs, min_per_motion=body.min_per_motion,
                                             demo_ids=ids, participant=code, version=version,
                                             q=body.latent_dim)
        _set_row(sessions, ModelSetRecord, ms_id, document=mset.to_json(), status="ready")
        return f"personal model set ({body.method}) from {len(demos)} demonstrations"

    job_id, _ = jobs.submit("fit_personal_model_set", ms_id, work,
                            _failure(sessions, ModelSetRecord, ms_id), owner_id=user.id)
    return PersonalModelSetOut.model_validate(row).model_copy(update={"job_id": job_id})


# ---------------------------------------------------------------------------- priors


def _utility_set(db: Session, ref: int, study_id: int) -> UtilitySetRecord:
    row = db.get(UtilitySetRecord, ref)
    if row is None or row.study_id != study_id:
        raise InvalidError.at(["body", "utility_set_id"], f"utility set {ref} is not a "
                              "utility set of this study")
    if row.status != "ready" or row.document is None:
        raise ConflictError("utility_set_id", f"utility set {ref} is {row.status}, not ready")
    return row


def _previous(db: Session, ref: int | None, participant: Participant) -> PriorSetRecord | None:
    if ref is None:
        return None
    row = db.get(PriorSetRecord, ref)
    if row is None or row.participant_id != participant.id:
        raise InvalidError.at(["body", "previous_prior_set_id"], f"prior set {ref} is not "
                              f"a prior set of participant {participant.code}")
    if row.document is None:
        raise ConflictError("previous_prior_set_id", f"prior set {ref} is {row.status}")
    return row


def confirmed_motions(db: Session, participant: Participant, include_recordings: bool,
                      gait_trials_as_other: bool) -> list[tuple[str, str]]:
    """(source id, category) of the participant's confirmed motions, oldest first:
    labelled trial segments, labelled recording segments and completed gait trials.

    A source id names the motion, not the row that holds it: a lift is its trial (or
    recording) and its first and last sample (`trial:12:300-399`). Saving a trial's
    segments replaces their rows; the lifts keep their ids, so a later prior set
    neither skips them nor counts them again."""
    sessions = _participant_sessions(db, participant.id)
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
    sessions = _participant_sessions(db, participant.id)
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


#: Attempts at a prior set's version number when other requests take it first.
VERSION_ATTEMPTS = 5


def learn_prior_set(db: Session, user: User, participant: Participant,
                    body: PriorSetIn) -> PriorSetRecord:
    """A new version of the participant's priors, inside the bound of `utility_set_id`
    (learned ones projected onto it, imported ones refused outside it); commits.

    The version is the participant's highest plus one, kept unique by the table: when
    another request stored that version first, this one starts again from the new
    highest (the document names its version, so it is learned again); after
    `VERSION_ATTEMPTS` such races, 409."""
    pid, code = participant.id, participant.code
    for _ in range(VERSION_ATTEMPTS):
        try:
            return _learn_prior_set(db, user, participant, body)
        except IntegrityError:
            db.rollback()
            if db.scalar(select(func.count()).select_from(Participant)
                         .where(Participant.id == pid)) == 0:
                raise
    raise ConflictError("prior_set", f"other prior sets of participant {code} were being "
                        "stored at the same time; try again")


def _learn_prior_set(db: Session, user: User, participant: Participant,
                     body: PriorSetIn) -> PriorSetRecord:
    utilities = _utility_set(db, body.utility_set_id, participant.study_id)
    bounds = PriorBounds.for_table(_table(utilities), (body.floor,) * N_CATEGORIES)
    previous = _previous(db, body.previous_prior_set_id, participant)
    version = 1 + (db.scalar(select(func.max(PriorSetRecord.version)).where(
        PriorSetRecord.participant_id == participant.id)) or 0)
    label = f"{participant.code}-priors-{version}"
    meta = {"participant": participant.code, "utility_set_id": utilities.id,
            "utility_set_name": utilities.name}
    params: dict[str, Any] = {"floor": body.floor}
    priors: LearnedPriors
    if body.method == "dirichlet":
        motions = confirmed_motions(db, participant, body.include_recordings,
                                    body.gait_trials_as_other)
        before = None
        if previous is not None and previous.document is not None:
            try:
                before = LearnedPriors.from_json(previous.document)
            except ValueError as exc:
                raise ConflictError("previous_prior_set_id", f"prior set {previous.id} is "
                                    f"not a valid priors document: {exc}") from None
        current = dict(motions)
        known = _source_labels(before)
        relabelled = sorted(s for s, lab in known.items() if current.get(s, lab) != lab)
        # Sets made before sources named the motion name segment rows instead.
        row_named = before is not None and any(
            s.startswith(("trial-segment:", "segment:")) for s in before.sources)
        continued = before
        if (relabelled or row_named) and before is not None:
            # A motion the previous set counted has a new label (or cannot be matched):
            # its old label is in the previous counts, so every motion is counted afresh
            # (once, with its label now), with the previous set's pseudo-counts and
            # forgetting.
            continued = None
            if before.method == "dirichlet":
                body = body.model_copy(update={"pseudo_count": before.pseudo_counts[0],
                                               "forgetting": before.forgetting})
            new = motions
        else:
            seen = set(before.sources) if before is not None else set()
            new = [(s, lab) for s, lab in motions if s not in seen]
        if not new and before is None:
            raise InvalidError.at(["body", "method"], f"participant {participant.code} has "
                                  "no confirmed motions yet: label trial or recording "
                                  "segments, or complete walking or stairs trials")
        labels = {**(known if continued is not None else {}), **dict(new)}
        priors = learn_from_confirmed(
            [lab for _, lab in new], bounds, sources=[s for s, _ in new], previous=continued,
            pseudo_counts=(body.pseudo_count,) * N_CATEGORIES, forgetting=body.forgetting,
            version=label, meta={**meta, SOURCE_LABELS: labels})
        params.update(pseudo_count=priors.pseudo_counts[0], forgetting=priors.forgetting,
                      new_motions=len(new), include_recordings=body.include_recordings,
                      gait_trials_as_other=body.gait_trials_as_other,
                      relabelled=relabelled[:50], recounted=continued is None
                      and before is not None)
    elif body.method == "label-shift-em":
        posts, train, sources = unconfirmed_posteriors(db, participant, body.window_s)
        try:
            priors = learn_from_unconfirmed(posts, train, bounds, sources=tuple(sources),
                                            version=label)
        except ValueError as exc:
            raise ConflictError("method", f"label-shift-em cannot learn from participant "
                                f"{participant.code}'s trials: {exc}") from None
        priors = LearnedPriors.from_json({**priors.to_json(),
                                          "meta": {**priors.meta, **meta}})
        params.update(window_s=body.window_s, motions=len(sources))
    else:
        values = tuple(EQUAL_PRIORS) if body.method == "equal" else tuple(body.values or ())
        problem = bounds.violation(values)
        if problem is not None:
            raise InvalidError.at(["body", "values"], "these priors could make the "
                                  "controller lock where equal priors would not, or leave a "
                                  f"motion below its floor: {problem}")
        priors = LearnedPriors(version=label, values=values, estimate=values, method="equal",
                               floors=bounds.floors,
                               roles=tuple(r.value for r in bounds.roles),
                               meta={**meta, "source": body.method})
    row = PriorSetRecord(study_id=participant.study_id, participant_id=participant.id,
                         version=version, name=body.name, method=body.method, status="ready",
                         utility_set_id=utilities.id,
                         previous_id=None if previous is None else previous.id,
                         params=params, document=priors.to_json(), created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "prior_set", row.id,
                 {"name": body.name, "method": body.method, "version": version,
                  "values": list(priors.values), "estimate": list(priors.estimate)})
    db.commit()
    return row


#: Where a learned set's document keeps each source's label when it was counted.
SOURCE_LABELS = "source_labels"


def _source_labels(priors: LearnedPriors | None) -> dict[str, str]:
    """Each counted source's label as counted (empty for a set that kept none)."""
    got = priors.meta.get(SOURCE_LABELS) if priors is not None else None
    if not isinstance(got, dict):
        return {}
    return {str(k): str(v) for k, v in got.items()}


def _table(utilities: UtilitySetRecord) -> np.ndarray:
    from controller.decision.utility_function import UtilitySet

    assert utilities.document is not None
    return np.asarray(UtilitySet.from_json(utilities.document).table.values)
