"""The demo study a newcomer finds on the first `make run`.

An account (`demo` / `exostudy-demo`, printed in the README), a study with six virtual
participants whose simulated demonstrations the default model set was fitted from, a
seventh virtual participant with an evaluation session and its counterbalanced trial
plan, and the utility set for the configured precompression. Created once, only into an
empty database, and only when `EXOSTUDY_DEMO` is on (the default), so a real study's
database never gets it. The server listens on 127.0.0.1 by default; change the password
(or turn the demo off) before exposing it.
"""

from __future__ import annotations

import logging
from datetime import date

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.db import audit
from backend.db.evidence_tables import ModelSetRecord, Trial, UtilitySetRecord
from backend.db.models import ConditionLabel, Participant, Study, StudySession, User
from backend.study import accounts
from backend.study.counterbalance import blinded_labels, controller_order
from controller.controllers.factory import needs_models
from controller.decision.utility_function import UtilitySet
from controller.intent.motion_model import ModelSet
from controller.sim.participant import VirtualParticipant

log = logging.getLogger(__name__)

DEMO_USER = "demo"
DEMO_PASSWORD = "exostudy-demo"
DEMO_STUDY = "Demo study (simulated)"
DATA_COLLECTION_SEEDS = (101, 102, 103, 104, 105, 106)
EVALUATION_SEED = 1
TASKS = ("squat-sequence", "stoop-sequence", "walking", "stairs")


def _participant(study_id: int, code: str, seed: int) -> Participant:
    vp = VirtualParticipant.from_seed(seed)
    return Participant(study_id=study_id, code=code, age=25 + seed % 30, sex=vp.sex,
                       height_m=round(vp.height_m, 3), mass_kg=round(vp.mass_kg, 1),
                       consent_date=date(2026, 1, 1),
                       notes=f"virtual participant, simulator seed {seed}")


def ensure_demo(db: Session, models: ModelSet, utilities: UtilitySet,
                precompression_pct: float) -> bool:
    """Create the demo study if the database has no account and no study yet."""
    if db.scalar(select(func.count()).select_from(User)) or db.scalar(
            select(func.count()).select_from(Study)):
        return False
    user = accounts.create_user(db, DEMO_USER, DEMO_PASSWORD, "admin", published=True)
    db.flush()
    study = Study(name=DEMO_STUDY, created_by=user.id, description=(
        "Virtual participants on the simulated exoskeleton. V01-V06 recorded the "
        "demonstrations the model set was fitted from; V07 is ready for evaluation "
        "(calibrate, then start the E-UMC trial)."))
    db.add(study)
    db.flush()
    for i, seed in enumerate(DATA_COLLECTION_SEEDS, start=1):
        p = _participant(study.id, f"V{i:02d}", seed)
        db.add(p)
        db.flush()
        db.add(StudySession(participant_id=p.id, kind="data_collection",
                            precompression_pct=precompression_pct,
                            notes="demonstrations recorded in simulation (squat and stoop "
                                  "sequences); the demo model set was fitted from them"))
    ms = ModelSetRecord(study_id=study.id, name="Simulated demonstrations V01-V06",
                        status="ready", document=models.to_json(), created_by=user.id,
                        params={"source": "simulated data collection",
                                "seeds": list(DATA_COLLECTION_SEEDS)})
    us = UtilitySetRecord(study_id=study.id, name=f"Simulated reference, {precompression_pct:g} %",
                          precompression_pct=precompression_pct,
                          human_source=f"simulated:{utilities.human_version}", status="ready",
                          document=utilities.to_json(), created_by=user.id)
    db.add_all([ms, us])
    v7 = _participant(study.id, "V07", EVALUATION_SEED)
    db.add(v7)
    db.flush()
    sess = StudySession(participant_id=v7.id, kind="evaluation",
                        precompression_pct=precompression_pct,
                        notes="the simulated device plays this participant (seed 1)")
    db.add(sess)
    db.flush()
    # V07 is the study's 7th participant: the same counterbalancing rule as any study.
    order = controller_order(6)
    for controller, label in blinded_labels(order).items():
        db.add(ConditionLabel(participant_id=v7.id, label=label, controller=controller))
    n = 0
    for controller in order:
        for task in TASKS:
            needs = needs_models(controller)
            db.add(Trial(session_id=sess.id, controller=controller, task=task, planned_order=n,
                         status="planned", model_set_id=ms.id if needs else None,
                         utility_set_id=us.id if needs else None))
            n += 1
    audit.record(db, "system", "create", "study", study.id, {"demo": True})
    db.commit()
    log.info("created the demo study; log in as %s", DEMO_USER)
    return True
