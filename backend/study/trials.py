"""The evaluation trials: the counterbalanced plan, and starting and stopping a trial on
the live path with exactly the configuration stored beside it.

The service behind `backend/api/routes/trials.py`; refusals are `backend.core.errors`.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Engine, delete, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.core.resources import version
from backend.db import audit
from backend.db.evidence_tables import LockEvent, ModelSetRecord, Trial, UtilitySetRecord
from backend.db.models import ConditionLabel, Participant, StudySession, User
from backend.db.personalisation import PriorSetRecord
from backend.lab.hub import Lab
from backend.live.runtime import Runtime
from backend.schemas.evidence import TrialPlanIn, TrialStartIn, TrialStopIn
from backend.schemas.live import SimulationChoice
from backend.study import activity, conditions, hardware_profiles
from backend.study.counterbalance import blinded_labels, condition_order, controller_order
from backend.study.recordings import check_simulation
from backend.worker.messages import Wearer
from controller.config import SettingError
from controller.controllers import registry
from controller.controllers.factory import needs_models
from controller.controllers.spec import ControllerSpec
from controller.device.base import SAMPLE_PERIOD_S


def _get(db: Session, model: Any, key: int, entity: str) -> Any:
    row = db.get(model, key)
    if row is None:
        raise NotFoundError(entity, key)
    return row


def _position(db: Session, participant: Participant) -> int:
    ids = list(db.scalars(select(Participant.id).where(Participant.study_id ==
                                                       participant.study_id)
                          .order_by(Participant.id)))
    return ids.index(participant.id)


def session_trials(db: Session, session_id: int) -> list[Trial]:
    """The session's trials in planned order; `NotFoundError` for an unknown session."""
    _get(db, StudySession, session_id, "session")
    return list(db.scalars(select(Trial).where(Trial.session_id == session_id)
                           .order_by(Trial.planned_order)))


def get(db: Session, trial_id: int) -> Trial:
    """The trial; `NotFoundError` if there is none."""
    trial: Trial = _get(db, Trial, trial_id, "trial")
    return trial


def lock_events(db: Session, trial_id: int) -> list[LockEvent]:
    """The trial's lock events in time order."""
    get(db, trial_id)
    return list(db.scalars(select(LockEvent).where(LockEvent.trial_id == trial_id)
                           .order_by(LockEvent.t, LockEvent.id)))


def run_of(db: Session, trial_id: int) -> int:
    """The run holding the trial's ticks; a conflict for a trial that has not run."""
    trial = get(db, trial_id)
    if trial.run_id is None:
        raise ConflictError("status", f"trial {trial.id} has not run")
    return trial.run_id


def plan(db: Session, user: User, session_id: int, body: TrialPlanIn) -> list[Trial]:
    """Create the session's trials in the counterbalanced order and assign the blinded
    labels; commits."""
    sess: StudySession = _get(db, StudySession, session_id, "session")
    if sess.kind != "evaluation":
        raise ConflictError("kind", f"session {sess.id} is a {sess.kind} session, not "
                            "evaluation")
    existing_plan = list(db.scalars(select(Trial).where(Trial.session_id == session_id)
                                    .order_by(Trial.planned_order)))
    replaced = [t.id for t in existing_plan]
    if existing_plan and not body.replace:
        raise ConflictError("trials", f"session {sess.id} already has a plan; send "
                            '"replace": true to replace it (allowed while none of its '
                            "trials has started)")
    ms = db.get(ModelSetRecord, body.model_set_id) if body.model_set_id else None
    us = db.get(UtilitySetRecord, body.utility_set_id) if body.utility_set_id else None
    _check_ready("model_set_id", "model set", body.model_set_id, ms)
    _check_ready("utility_set_id", "utility set", body.utility_set_id, us)
    if existing_plan:
        _discard_plan(db, sess, existing_plan)
    participant: Participant = _get(db, Participant, sess.participant_id, "participant")
    baseline_tasks = _baseline_tasks(body)
    order = controller_order(_position(db, participant), body.include_eumc,
                             include_baselines=body.include_baselines)
    personal, prior_set = _check_conditions(db, body, participant, us)
    units = condition_order(_position(db, participant),
                            conditions.variants_of(order, body.conditions), body.include_eumc,
                            include_baselines=body.include_baselines)
    keys = [conditions.key(c, v) for c, v in units]
    labels = (blinded_labels(order) if keys == order
              else conditions.assign_labels(db, participant.id, keys))
    existing = {c.controller: c.label for c in db.scalars(
        select(ConditionLabel).where(ConditionLabel.participant_id == participant.id))}
    for controller, label in labels.items():
        if controller not in existing:
            db.add(ConditionLabel(participant_id=participant.id, label=label,
                                  controller=controller))
    trials: list[Trial] = []
    if body.demonstrations is not None:  # first: the personal set is fitted from it
        trials.append(Trial(session_id=session_id, controller="none",
                            task=conditions.DEMONSTRATION_TASK, planned_order=0,
                            status="planned", demonstrations=body.demonstrations.model_dump()))
    baselines = set(registry.baselines())
    for controller, variant in units:
        sets = needs_models(controller)
        own = sets and conditions.uses_personal(variant)
        for task in baseline_tasks if controller in baselines else body.tasks:
            trials.append(Trial(
                session_id=session_id, controller=controller, task=task,
                planned_order=len(trials), status="planned",
                model_set_id=(personal if own else body.model_set_id) if sets else None,
                utility_set_id=body.utility_set_id if sets else None,
                condition=conditions.key(controller, variant),
                models="personal" if own else "population",
                prior_set_id=prior_set if sets and conditions.uses_priors(variant) else None))
    db.add_all(trials)
    db.flush()
    audit.record(db, user, "plan", "session", session_id,
                 {"order": order, "tasks": body.tasks, "baseline_tasks": baseline_tasks,
                  "labels": labels,
                  "conditions": keys, "personal_model_set_id": personal,
                  "prior_set_id": prior_set, "demonstrations": None if body.demonstrations
                  is None else body.demonstrations.model_dump(),
                  "replaced_trials": replaced})
    db.commit()
    return trials


#: Words that make a task a lift task, for which baselines are planned by default:
#: muscle activity is measured in lifts; walking and stairs judge false locks, which
#: mean nothing without a controller.
LIFT_TASK_WORDS = ("squat", "stoop", "lift")


def is_lift_task(task: str) -> bool:
    """Whether a task's name says it is lifting."""
    name = task.casefold()
    return any(w in name for w in LIFT_TASK_WORDS)


def _baseline_tasks(body: TrialPlanIn) -> list[str]:
    """The tasks the baseline conditions are planned for: as asked, or the plan's lift
    tasks; a plan with baselines and no task for them is refused (422)."""
    if not body.include_baselines:
        return []
    if body.baseline_tasks is not None:
        return list(dict.fromkeys(body.baseline_tasks))
    lifts = [t for t in body.tasks if is_lift_task(t)]
    if not lifts:
        raise InvalidError.at(["body", "baseline_tasks"], (
            f"include_baselines: none of the tasks {body.tasks} is a lift task (with "
            f"{', '.join(LIFT_TASK_WORDS)} in its name); name the baselines' tasks in "
            "baseline_tasks"))
    return lifts


def _check_conditions(db: Session, body: TrialPlanIn, participant: Participant,
                      utilities: UtilitySetRecord | None) -> tuple[int | None, int | None]:
    """The personal model set and prior set the plan's conditions need (422 naming what
    is missing or wrong): a personal condition needs a personal set named, one to be
    fitted from the plan's demonstration block, or one the participant already has; a
    priors condition needs a prior set of this participant inside the safety bound of
    the plan's utility set."""
    population = db.get(ModelSetRecord, body.model_set_id) if body.model_set_id else None
    if population is not None and population.kind == "personal":
        raise InvalidError.at(["body", "model_set_id"], f"model set {population.id} is a "
                              "personal model set: name it as personal_model_set_id with a "
                              '"personal" condition')
    personal_wanted = any(conditions.uses_personal(v) for v in body.conditions)
    priors_wanted = any(conditions.uses_priors(v) for v in body.conditions)
    if body.personal_model_set_id is not None and not personal_wanted:
        raise InvalidError.at(["body", "personal_model_set_id"], "no condition uses "
                              'personal models: add "personal" to conditions')
    if body.prior_set_id is not None and not priors_wanted:
        raise InvalidError.at(["body", "prior_set_id"], "no condition uses a prior set: "
                              'add "population+priors" or "personal+priors" to conditions')
    personal = body.personal_model_set_id
    if personal is not None:
        conditions.check_personal_set(db, personal, participant,
                                      ["body", "personal_model_set_id"])
    elif personal_wanted and body.demonstrations is None \
            and conditions.latest_personal_set(db, participant.id) is None:
        raise InvalidError.at(["body", "conditions"], "a personal-models condition needs "
                              "a personal model set: give personal_model_set_id, or plan a "
                              "demonstration block (demonstrations) and fit the set from it "
                              "before those trials start")
    if priors_wanted and body.prior_set_id is None:
        raise InvalidError.at(["body", "prior_set_id"], "a +priors condition needs the "
                              "participant's prior set")
    if body.prior_set_id is not None:
        conditions.check_plan_prior_set(db, body.prior_set_id, participant, utilities)
    return personal, body.prior_set_id


def _check_ready(key: str, entity: str, ref: int | None,
                 row: ModelSetRecord | UtilitySetRecord | None) -> None:
    """A plan names only sets that exist and are ready: one still fitting may yet fail,
    and trials planned with it could never start."""
    if ref is None:
        return
    if row is None:
        raise InvalidError.at(["body", key], f"{entity} {ref} does not exist")
    if row.status != "ready" or row.document is None:
        raise ConflictError(key, f"{entity} {ref} is {row.status}, not ready: plan with a "
                            f"ready {entity}" + (f" ({row.error})" if row.error else ""))


def _discard_plan(db: Session, sess: StudySession, trials: list[Trial]) -> None:
    """Make way for a new plan (asked for with `replace`), only while no trial of the
    old one has started: a started trial's ticks, configuration and outcome are
    evidence."""
    started = [f"{t.id} ({t.status})" for t in trials if t.status != "planned"]
    if started:
        raise ConflictError("trials", f"session {sess.id}'s plan cannot be replaced: "
                            f"trial(s) {', '.join(started[:20])} have started and are kept "
                            "with their data")
    ids = [t.id for t in trials]
    # Conditional: a trial started by a concurrent request since the read stays.
    gone = db.execute(delete(Trial).where(Trial.id.in_(ids), Trial.status == "planned")
                      .execution_options(synchronize_session="fetch"))
    if gone.rowcount != len(ids):  # type: ignore[attr-defined]
        db.rollback()
        raise ConflictError("trials", f"session {sess.id}'s plan cannot be replaced: a "
                            "trial of it has just started")


def _check_sets_belong(db: Session, trial: Trial, sess: StudySession, ms: ModelSetRecord,
                       us: UtilitySetRecord) -> None:
    """Re-checked at start, whatever the trial row says (a row may have been altered
    since it was planned): the model, utility and prior sets are of the participant's
    study, a personal model set and a prior set are the participant's own, and the
    trial's condition is one that runs them (409 naming the mismatch)."""
    part = db.get(Participant, sess.participant_id)
    assert part is not None
    for key, row, entity in (("model_set_id", ms, "model set"),
                             ("utility_set_id", us, "utility set")):
        if row.study_id != part.study_id:
            raise ConflictError(key, f"{entity} {row.id} of trial {trial.id} is of study "
                                f"{row.study_id}, not the participant's study "
                                f"{part.study_id}")
    personal_condition = trial.models == "personal" or "+personal" in trial.condition
    if ms.kind == "personal" and ms.participant_id != part.id:
        raise ConflictError("model_set_id", f"model set {ms.id} of trial {trial.id} is a "
                            f"personal model set of another participant, not {part.code}")
    if personal_condition and ms.kind != "personal":
        raise ConflictError("model_set_id", f"trial {trial.id}'s condition "
                            f"{trial.condition!r} runs personal models but model set "
                            f"{ms.id} is a {ms.kind} model set")
    if trial.condition and not personal_condition and ms.kind == "personal":
        raise ConflictError("model_set_id", f"trial {trial.id}'s condition "
                            f"{trial.condition!r} runs population models but model set "
                            f"{ms.id} is a personal model set")
    if trial.prior_set_id is None:
        return
    if not trial.condition.endswith("+priors"):
        raise ConflictError("prior_set_id", f"trial {trial.id}'s condition "
                            f"{trial.condition!r} runs the equal priors but the trial names "
                            f"prior set {trial.prior_set_id}")
    prior = db.get(PriorSetRecord, trial.prior_set_id)
    if prior is not None and (prior.participant_id != part.id
                              or prior.study_id != part.study_id):
        raise ConflictError("prior_set_id", f"prior set {prior.id} of trial {trial.id} is "
                            f"another participant's, not {part.code}'s")


def trial_spec(db: Session, runtime: Runtime, trial: Trial, sess: StudySession,
               rate_hz: float | None, sim: SimulationChoice | None = None
               ) -> tuple[ControllerSpec, dict[str, Any]]:
    """The trial's controller configuration and the snapshot stored with the trial:
    the server's defaults at the session's precompression, `rate_hz` for every
    controller if given, and the trial's own model and utility sets inline (so the
    stored snapshot is what ran, whatever the files hold later). With `sim`, the trial
    runs on that simulated wearer: another virtual participant's calibration does not
    apply, and the snapshot names that wearer and the speed it runs at."""
    overrides: dict[str, Any] = {"precompression_pct": sess.precompression_pct}
    if rate_hz is not None:
        overrides.update(umc_rate_hz=rate_hz, eumc_triggered_rate_hz=rate_hz,
                         pec_rate_hz=rate_hz)
    try:
        spec = runtime.controller_spec(trial.controller, overrides,
                                       None if sim is None else sim.seed)
    except SettingError as exc:
        raise InvalidError.at(["body", "rate_hz" if exc.field.endswith("rate_hz")
                               else exc.field], exc.problem) from exc
    s = runtime.settings
    snapshot: dict[str, Any] = {"controller": trial.controller, "task": trial.task,
                                "device": {"kind": s.device_kind, "seed": s.device_seed,
                                           "script": s.device_script}}
    if sim is not None:
        snapshot["device"].update(seed=sim.seed, script=sim.script)
        snapshot["simulation"] = {"seed": sim.seed, "script": sim.script,
                                  "speed": s.device_speed if sim.speed is None else sim.speed}
    if trial.condition:
        snapshot["condition"] = trial.condition
    if trial.demonstrations is not None:
        snapshot["demonstrations"] = trial.demonstrations
    if needs_models(trial.controller):
        ms = db.get(ModelSetRecord, trial.model_set_id) if trial.model_set_id else None
        us = db.get(UtilitySetRecord, trial.utility_set_id) if trial.utility_set_id else None
        if ms is None and trial.models == "personal":
            ms = conditions.latest_personal_set(db, sess.participant_id)
            if ms is None:
                raise ConflictError("model_set_id", "the trial's condition runs personal "
                                    "models and the participant has no ready personal "
                                    "model set: fit one from the demonstration block "
                                    "(POST /api/participants/{id}/personal-model-sets)")
            trial.model_set_id = ms.id  # stored with the trial when it starts
        if ms is None or ms.document is None:
            raise ConflictError("model_set_id", "the trial needs a fitted model set")
        if us is None or us.document is None:
            raise ConflictError("utility_set_id", "the trial needs a computed utility set")
        _check_sets_belong(db, trial, sess, ms, us)
        if abs(us.precompression_pct - sess.precompression_pct) > 1e-9:
            raise ConflictError("utility_set_id", f"utilities were computed for "
                                f"{us.precompression_pct:g} % but the session runs at "
                                f"{sess.precompression_pct:g} %")
        priors = None
        if trial.prior_set_id is not None:
            row = db.get(PriorSetRecord, trial.prior_set_id)
            if row is None:
                raise ConflictError("prior_set_id", f"prior set {trial.prior_set_id} of the "
                                    "trial's condition no longer exists")
            priors = conditions.checked_priors(row, us)
            snapshot["priors"] = conditions.snapshot_of_priors(row, priors)
        try:
            spec = replace(spec, models=ms.document, models_path=None,
                           utilities=us.document, utilities_path=None, priors=priors)
        except SettingError as exc:
            raise ConflictError(exc.field, exc.problem) from exc
        snapshot["model_set"] = conditions.snapshot_of_models(ms)
        snapshot["utility_set"] = {"id": us.id, "name": us.name,
                                   "precompression_pct": us.precompression_pct,
                                   "human_source": us.human_source,
                                   "other_rule": us.document.get("meta", {}).get("other_rule")}
    settings = spec.settings.to_json()
    if registry.needs_calibration(trial.controller) and settings.get("calibration") is None:
        raise ConflictError("calibration", f"the {registry.label(trial.controller)} needs a "
                            "calibration: have the participant stand still and POST "
                            "/api/worker/calibrate")
    snapshot["settings"] = settings
    return spec, snapshot


async def start(db: Session, user: User, runtime: Runtime, lab: Lab, trial_id: int,
                body: TrialStartIn) -> Trial:
    """Run the trial's controller and mark it running, under the runtime's activity
    lock (with its start marker on the lab's LSL stream); a second running trial refused
    by the database leaves the worker idle."""
    async with runtime.activity:
        try:
            return await _start(db, user, runtime, lab, trial_id, body)
        except IntegrityError as exc:
            db.rollback()
            # The worker may already run the refused trial's controller: back to none.
            await runtime.idle()
            raise ConflictError("trial", "another trial is running: the database "
                                "refused a second") from exc


async def _start(db: Session, user: User, runtime: Runtime, lab: Lab, trial_id: int,
                 body: TrialStartIn) -> Trial:
    trial: Trial = _get(db, Trial, trial_id, "trial")
    if trial.status != "planned":
        raise ConflictError("status", f"trial {trial.id} is {trial.status}; plan a new one "
                            "to repeat it")
    activity.ensure_idle(db)
    sess: StudySession = _get(db, StudySession, trial.session_id, "session")
    sim = body.simulation
    if sim is not None:
        check_simulation(runtime, sim, "trial")
    spec, snapshot = trial_spec(db, runtime, trial, sess, body.rate_hz, sim)
    if body.duration_s is not None:
        snapshot["duration_s"] = body.duration_s
    snapshot["exostudy_version"] = version()
    try:
        run_id = await runtime.switch_controller(
            spec, max_ticks=None if body.duration_s is None
            else round(body.duration_s / SAMPLE_PERIOD_S),
            wearer=None if sim is None else Wearer(sim.seed, sim.script, sim.speed))
    except RuntimeError as exc:
        # No trial without its controller, and no controller without its trial: a
        # switch that may still take effect later is countermanded.
        runtime.release()
        raise ConflictError("worker", str(exc)) from exc
    trial.run_id = run_id
    trial.status = "running"
    trial.started_at = datetime.now(UTC)
    trial.config_snapshot = snapshot
    trial.hardware_profile_id = hardware_profiles.active_id(db)
    audit.record(db, user, "start", "trial", trial.id, {"run_id": run_id})
    db.commit()
    await lab.trial_marker(db, trial, "trial_start")  # LSL marker, stored
    return trial


async def stop(db: Session, engine: Engine, user: User, runtime: Runtime, lab: Lab,
               trial_id: int, body: TrialStopIn) -> Trial:
    """End a running trial as completed or aborted: the worker back to `none`, then its
    tick count, quality flags and lock events from the stored ticks."""
    async with runtime.activity:
        trial: Trial = _get(db, Trial, trial_id, "trial")
        if trial.status != "running":
            raise ConflictError("status", f"trial {trial.id} is {trial.status}, not running")
        await runtime.idle()  # a worker that died has stored the trial's ticks up to then
        runtime.recorder.flush()
        if not activity.close_trial(db, engine, trial.id, body.outcome, body.reason):
            db.refresh(trial)  # closed meanwhile: its worker stopped
            raise ConflictError("status", f"trial {trial.id} is {trial.status}, not running")
        db.refresh(trial)
        audit.record(db, user, "stop", "trial", trial.id, body.model_dump())
        db.commit()
        await lab.trial_marker(db, trial, "trial_stop")  # LSL marker, stored
        return trial
