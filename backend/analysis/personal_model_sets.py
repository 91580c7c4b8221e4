"""A participant's personal model sets: checked, recorded with their provenance, then
fitted as a background job (like a population model set), and listed.

The service behind the personal-model-set routes of
`backend/api/routes/personalisation.py`; refusals are `backend.core.errors`. The pure
fits are `controller.intent.personal_models`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session, sessionmaker

from backend.analysis import tick_queries
from backend.analysis.fitting import _failure, _set_row
from backend.analysis.jobs import JobRunner
from backend.analysis.participant_motions import demonstrations, known_participant
from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db import audit
from backend.db.evidence_tables import ModelSetRecord
from backend.db.models import Study, User
from backend.schemas.personalisation import PersonalModelSetIn, PersonalModelSetOut
from controller.intent.motion_model import ModelSet
from controller.intent.personal_models import adapt_model_set, fit_participant_model_set
from controller.tick_record import MODEL_NAMES


def participant_sets(db: Session, participant_id: int) -> list[ModelSetRecord]:
    """The participant's personal model sets, oldest first; `NotFoundError` for an
    unknown participant."""
    known_participant(db, participant_id)
    return list(db.scalars(select(ModelSetRecord).where(
        ModelSetRecord.participant_id == participant_id, ModelSetRecord.kind == "personal")
        .order_by(ModelSetRecord.id)))


def study_sets(db: Session, study_id: int) -> list[ModelSetRecord]:
    """Every personal model set of the study's participants, oldest first;
    `NotFoundError` for an unknown study."""
    if db.get(Study, study_id) is None:
        raise NotFoundError("study", study_id)
    return list(db.scalars(select(ModelSetRecord).where(
        ModelSetRecord.study_id == study_id, ModelSetRecord.kind == "personal")
        .order_by(ModelSetRecord.id)))


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
                     jobs: JobRunner, user: User, participant_id: int,
                     body: PersonalModelSetIn) -> PersonalModelSetOut:
    """Check the participant (`NotFoundError`), the demonstrations (theirs, labelled
    squat or stoop) and the population set, record the personal set as `fitting` with
    its provenance and queue the fit; the answer carries the job id."""
    person = known_participant(db, participant_id)
    demos = demonstrations(db, person, body)
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
    population = _population_set(db, body.population_model_set_id, person.study_id)
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
    row = ModelSetRecord(study_id=person.study_id, name=body.name, status="fitting",
                         params=params, created_by=user.id, kind="personal",
                         segment_ids=[int(d.source.split(":")[1]) for d in demos
                                      if d.source.startswith("segment:")],
                         method="map" if body.method == "map" else "ppca",
                         participant_id=person.id,
                         base_model_set_id=body.population_model_set_id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "model_set", row.id,
                 {"name": body.name, "kind": "personal", "participant_id": person.id,
                  **params})
    db.commit()
    ms_id, code, study_id = row.id, person.code, person.study_id
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
