"""Virtual cohorts: the paper's evaluation protocol on many simulated participants.

A cohort samples `participants` virtual people from the simulated population
(`VirtualParticipant.from_seed`: its documented distributions of body size, movement
depth, speed, asymmetry, donning offsets), has each perform the paper's evaluation
script (`paper-evaluation`: squat and stoop sequences with a 5 kg box, the 10 m walk,
the stairs) once per controller, replays those angles through every chosen controller
with the batch replay kernel (`controller.runner.replay.replay_columns`: the same tick code as
the live loop) and evaluates every metric of the paper's tables per participant from
the simulation's ground truth.

Choices, stated:
- Each controller gets its own repetition of the script (`realise(..., repetition=i)`:
  new draws of every duration and depth), as a real participant performs a new trial
  per controller; replaying one trajectory through all three would make the pairs
  more alike than any study's can be, and overstate power.
- The E-UMC is calibrated as in the live protocol: on the first second of the trial in
  which the wearer stands still enough (the live calibration's threshold), retried
  along the trial's standing periods.
- Participant j of a cohort with seed S is simulator seed `1_000_000 + S * 10_000 + j`,
  away from the seeds the default motion models were fitted from (101..106): no
  virtual participant is also a demonstrator.
- One model set and utility set for the whole cohort (the paper fitted its models on
  another group than it evaluated), given by the caller or fitted from the simulated
  data collection.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from controller.config import ControllerConfig
from controller.controllers import registry
from controller.controllers.factory import make_from_spec, needs_models
from controller.controllers.spec import ControllerSpec
from controller.decision.utility_function import UtilitySet
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import lifts_from_truth, trials_from_truth
from controller.evaluation.metrics import DecisionOutcome
from controller.evaluation.muscle_activity import (
    ParticipantMuscles,
    SessionEmg,
    lift_trial,
    record_baselines,
    record_condition,
)
from controller.evaluation.study import RecordingEvaluation, evaluate_recording
from controller.intent.calibration import CalibrationError, calibrate
from controller.intent.motion_model import ModelSet
from controller.runner.replay import AngleRecording, replay_columns
from controller.sim.participant import VirtualParticipant
from controller.sim.scripts import get_script, realise


def cohort_controllers() -> tuple[str, ...]:
    """The controllers a cohort runs by default and may run: those that enter a trial
    plan (`controller.controllers.registry.PlanPlace`), in plan rank order."""
    return tuple(r.name for r in registry.planned())


MAX_PARTICIPANTS = 10_000
SEED_BASE = 1_000_000
#: The live calibration's window (1 s at 100 Hz) and the step between retries (0.5 s).
CALIBRATION_WINDOW = 100
CALIBRATION_STEP = 50


@dataclass(frozen=True)
class MetricSpec:
    """One per-participant metric: its name, what it means and its unit."""

    name: str
    label: str
    unit: str
    #: Only for controllers that estimate intent (the PEC has no posterior).
    intent_only: bool = False


#: Every metric of the paper's tables, per participant and controller.
METRICS: tuple[MetricSpec, ...] = (
    MetricSpec("recognised_pct", "lifts recognised (posterior >= 0.5, first half)", "%",
               intent_only=True),
    MetricSpec("correct_pct", "correct first lock decision, all lifts", "%"),
    MetricSpec("correct_sq_pct", "correct first lock decision, squats (SQ)", "%"),
    MetricSpec("correct_as_pct", "correct first lock decision, stoops (AS)", "%"),
    MetricSpec("wrong", "wrong first lock decisions", "lifts"),
    MetricSpec("missed", "missed lock decisions", "lifts"),
    MetricSpec("fp_walking", "false positive lock signals, walking (W)", "count"),
    MetricSpec("fp_stairs", "false positive lock signals, stair walking (SW)", "count"),
    MetricSpec("fp_total", "false positive lock signals, W + SW", "count"),
    MetricSpec("onset_to_lock_s", "onset to first lock, median over lifts", "s"),
    MetricSpec("peak_torque_squat_nm", "peak exoskeleton torque in squats, mean of both "
               "hips", "Nm"),
    MetricSpec("support_asymmetry_nm", "support asymmetry in stoops: |left - right| peak "
               "torque", "Nm"),
)
METRIC_NAMES: tuple[str, ...] = tuple(m.name for m in METRICS)


@dataclass(frozen=True)
class CohortConfig:
    """What to simulate."""

    participants: int = 100
    seed: int = 1
    controllers: tuple[str, ...] = field(default_factory=cohort_controllers)
    script: str = "paper-evaluation"
    #: None: the paper's rates (UMC 10 Hz, PEC 100 Hz, E-UMC 100/10 Hz); else every
    #: controller at this rate.
    rate_hz: float | None = None
    precompression_pct: float = 25.0
    #: Muscle activity (`controller.evaluation.muscle_activity`): sEMG of every lift
    #: trial, and the baseline conditions (springs free, no exoskeleton) as extra
    #: lift trials. Off by default: it costs about 0.6 s per trial.
    emg: bool = False

    def __post_init__(self) -> None:
        if not 2 <= self.participants <= MAX_PARTICIPANTS:
            raise ValueError(f"participants: must be within 2..{MAX_PARTICIPANTS}, got "
                             f"{self.participants}")
        if not 0 <= self.seed <= 99_999:
            raise ValueError(f"seed: must be within 0..99999, got {self.seed}")
        known = cohort_controllers()
        unknown = [c for c in self.controllers if c not in known]
        if unknown or not self.controllers:
            raise ValueError(f"controllers: choose from {','.join(known)}, got "
                             f"{','.join(self.controllers) or 'none'}")
        if len(set(self.controllers)) != len(self.controllers):
            raise ValueError("controllers: each controller once")
        get_script(self.script)  # ValueError names the valid scripts
        if self.rate_hz is not None and not 1.0 <= self.rate_hz <= 100.0:
            raise ValueError(f"rate_hz: must be within 1..100 Hz, got {self.rate_hz}")
        if not 0.0 <= self.precompression_pct <= 100.0:
            raise ValueError("precompression_pct: must be within 0..100")

    def participant_seed(self, j: int) -> int:
        """Simulator seed of participant j (0-based)."""
        return SEED_BASE + self.seed * MAX_PARTICIPANTS + j

    def settings(self) -> ControllerConfig:
        """The controllers' settings (rates, precompression)."""
        cfg = ControllerConfig(precompression_pct=self.precompression_pct)
        return cfg if self.rate_hz is None else cfg.at_rate(self.rate_hz)


@dataclass(frozen=True)
class ParticipantResult:
    """One virtual participant: who they are and their metrics per controller."""

    index: int
    seed: int
    body: dict[str, Any]
    #: controller -> metric -> value (NaN where undefined, e.g. recognised for the PEC)
    metrics: dict[str, dict[str, float]]
    calibration_attempts: int = 0
    #: Muscle activity per condition (`CohortConfig.emg`), else None.
    muscles: ParticipantMuscles | None = None


@dataclass
class Cohort:
    """The simulated cohort: its configuration and one result per participant."""

    config: CohortConfig
    participants: list[ParticipantResult] = field(default_factory=list)
    models_version: str = ""
    utilities_version: str = ""

    def values(self, controller: str, metric: str) -> np.ndarray:
        """One value per participant (participant order)."""
        return np.array([p.metrics[controller][metric] for p in self.participants],
                        dtype=np.float64)


def participant_body(p: VirtualParticipant) -> dict[str, Any]:
    """The documented traits of a virtual participant, for the outputs."""
    return {"sex": p.sex, "mass_kg": p.mass_kg, "height_m": p.height_m,
            "speed": round(p.speed, 3), "squat_depth_deg": round(p.squat_depth_deg, 1),
            "stoop_depth_deg": round(p.stoop_depth_deg, 1),
            "asymmetry": round(p.asymmetry, 4),
            "offset_deg": [round(x, 2) for x in p.offset_deg]}


def trial_recording(p: VirtualParticipant, seed: int, script: str,
                    repetition: int) -> AngleRecording:
    """What the exoskeleton's encoders see in one trial: the wearer's hip flexion plus
    the exoskeleton's donning offset and drift, with the simulation's ground truth. The
    hip moments are not simulated: nothing in the replay reads them."""
    traj = realise(get_script(script), p, seed, repetition, moments=False)
    q = traj.theta + p.encoder_offset(traj.t)
    return AngleRecording(traj.t, q, traj.activity_names().tolist(),
                          traj.lift.astype(np.int64))


def calibrated(settings: ControllerConfig, rec: AngleRecording,
                start: np.ndarray) -> tuple[ControllerConfig, int]:
    """The E-UMC settings calibrated on the first still second of the trial, and the
    number of windows tried (as the experimenter retries while the wearer moves)."""
    attempts = 0
    for s in range(0, rec.q.shape[0] - CALIBRATION_WINDOW, CALIBRATION_STEP):
        attempts += 1
        try:
            cal = calibrate(rec.q[s:s + CALIBRATION_WINDOW], start)
        except CalibrationError:
            continue
        return settings.with_calibration(cal.offset_left, cal.offset_right), attempts
    raise ValueError("the wearer never stood still for a second: no E-UMC calibration")


def _pct(k: int, n: int) -> float:
    return 100.0 * k / n if n else math.nan


def recording_metrics(ev: RecordingEvaluation) -> dict[str, float]:
    """Every metric of `METRICS` from one evaluated trial."""
    lifts = list(ev.lifts)
    sq = [o for o in lifts if o.lift.kind == "squat"]
    st = [o for o in lifts if o.lift.kind != "squat"]

    def correct(os_: Sequence[Any]) -> int:
        return sum(1 for o in os_ if o.decision == DecisionOutcome.CORRECT)

    rec = [o.recognised for o in lifts]
    recognised = (math.nan if not lifts or all(r is None for r in rec)
                  else _pct(sum(1 for r in rec if r), len(lifts)))
    fp_w = sum(f.signals for f in ev.false_positives if f.trial.kind == "walking")
    fp_s = sum(f.signals for f in ev.false_positives if f.trial.kind == "stair_walking")
    locks = np.array([o.first_lock_s for o in lifts], dtype=np.float64)
    locks = locks[np.isfinite(locks)]
    sq_peak = [0.5 * (o.peak_torque_left + o.peak_torque_right) for o in sq]
    asym = [abs(o.peak_torque_left - o.peak_torque_right) for o in st]
    return {
        "recognised_pct": recognised,
        "correct_pct": _pct(correct(lifts), len(lifts)),
        "correct_sq_pct": _pct(correct(sq), len(sq)),
        "correct_as_pct": _pct(correct(st), len(st)),
        "wrong": float(sum(1 for o in lifts if o.decision == DecisionOutcome.WRONG)),
        "missed": float(sum(1 for o in lifts if o.decision == DecisionOutcome.MISSED)),
        "fp_walking": float(fp_w),
        "fp_stairs": float(fp_s),
        "fp_total": float(fp_w + fp_s),
        "onset_to_lock_s": float(np.median(locks)) if locks.size else math.nan,
        "peak_torque_squat_nm": float(np.nanmean(sq_peak)) if sq_peak else math.nan,
        "support_asymmetry_nm": float(np.nanmean(asym)) if asym else math.nan,
    }


def replay_trial(rec: AngleRecording, name: str, settings: ControllerConfig,
                 start: np.ndarray, docs: tuple[dict[str, Any], dict[str, Any]],
                 participant: str) -> tuple[TickData, RecordingEvaluation, int]:
    """One trial of a virtual participant through controller `name`, as the live protocol
    runs it: calibrated first when the controller needs it (`calibrated`), replayed with
    the live tick code, evaluated against the simulation's truth. `docs`: the model and
    utility sets' JSON documents. Returns the ticks, the evaluation and the calibration
    windows tried (0 without calibration). The one replay of a cohort's trial: the
    replication's `cohort` engine runs its protocol through it too."""
    attempts = 0
    if registry.needs_calibration(name):
        settings, attempts = calibrated(settings, rec, start)
    sets = needs_models(name)
    spec = ControllerSpec(name, settings, models=docs[0] if sets else None,
                          utilities=docs[1] if sets else None)
    # Checked once (the truth columns are converted to text here), read three times.
    cols = TickData.of(replay_columns(rec, make_from_spec(spec), settings.precompression_pct))
    ev = evaluate_recording(cols, participant, name, lifts_from_truth(cols),
                            trials_from_truth(cols))
    return cols, ev, attempts


def simulate_participant(cfg: CohortConfig, j: int, models: ModelSet,
                         utilities: UtilitySet,
                         docs: tuple[dict[str, Any], dict[str, Any]] | None = None
                         ) -> ParticipantResult:
    """Participant j: one trial per controller, replayed and evaluated. `docs`: the
    models' and utilities' JSON documents, if the caller already has them."""
    seed = cfg.participant_seed(j)
    p = VirtualParticipant.from_seed(seed)
    settings = cfg.settings()
    start = models.start_posture()
    models_doc, utilities_doc = docs if docs is not None else (models.to_json(),
                                                               utilities.to_json())
    out: dict[str, dict[str, float]] = {}
    attempts = 0
    session = SessionEmg(p) if cfg.emg else None
    for i, name in enumerate(cfg.controllers):
        if session is None:
            rec = trial_recording(p, seed, cfg.script, repetition=i)
        else:
            rec, human_nm = lift_trial(p, seed, cfg.script, repetition=i)
        cols, ev, tried = replay_trial(rec, name, settings, start,
                                       (models_doc, utilities_doc), f"V{j + 1:04d}")
        attempts = tried or attempts
        out[name] = recording_metrics(ev)
        if session is not None:
            record_condition(session, name, cols, human_nm)
    if session is not None:
        record_baselines(session, seed, cfg.script, first_repetition=len(cfg.controllers))
    return ParticipantResult(j, seed, participant_body(p), out, attempts,
                             session.result() if session is not None else None)


def default_model_set(progress: Callable[[float], None] | None = None) -> ModelSet:
    """Motion models fitted from the simulated data collection (six demonstrators)."""
    from controller.sim.demonstrations import simulated_model_set

    return simulated_model_set(progress=progress)


def default_utilities(precompression_pct: float) -> UtilitySet:
    """Utilities from the simulated reference human dataset."""
    from controller.decision.utility_function import compute_utilities
    from controller.sim.human_dataset import reference_dataset

    return compute_utilities(reference_dataset(), precompression_pct)


_POOL_SETS: tuple[CohortConfig, ModelSet, UtilitySet, tuple[dict[str, Any],
                                                             dict[str, Any]]] | None = None


def _pool_init(cfg: CohortConfig, models_doc: dict[str, Any],
               utilities_doc: dict[str, Any]) -> None:
    global _POOL_SETS
    _POOL_SETS = (cfg, ModelSet.from_json(models_doc), UtilitySet.from_json(utilities_doc),
                  (models_doc, utilities_doc))


def _pool_participant(j: int) -> ParticipantResult:
    assert _POOL_SETS is not None, "worker process not initialised"
    cfg, models, utilities, docs = _POOL_SETS
    return simulate_participant(cfg, j, models, utilities, docs)


def _start_method() -> str:
    """"fork" where the platform has it and this process runs no other thread (the
    command line): the workers start at once with the modules and the compiled kernels
    the parent has already loaded, where "spawn" re-imports and reloads them in each
    (about a second of CPU per worker). Beside other threads (the server's jobs) a fork
    could copy a lock that one of them holds, so there: "spawn"."""
    import multiprocessing as mp
    import threading

    if threading.active_count() == 1 and "fork" in mp.get_all_start_methods():
        return "fork"
    return "spawn"


def auto_processes(participants: int) -> int:
    """Processes worth starting for a cohort of `participants` on this machine: one per
    core the process may use, but one per 20 participants at most (below that a worker
    does too little to repay its start)."""
    import os

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (
        os.cpu_count() or 1)
    return max(1, min(cores, participants // 20))


def simulate_cohort(
    cfg: CohortConfig,
    models: ModelSet | None = None,
    utilities: UtilitySet | None = None,
    progress: Callable[[float], None] | None = None,
    processes: int = 1,
) -> Cohort:
    """Every participant of the cohort through every chosen controller.

    `progress(fraction)` is called after each participant (models and utilities, when
    fitted here, take the first tenth). `processes` > 1 spreads the participants over
    that many processes (`_start_method`: forked from a single-threaded caller, which
    simulates the first participant itself before, so that the workers inherit the
    compiled kernels it loaded); the result is the same, participant by participant,
    as with one.
    """
    report = progress or (lambda _f: None)
    if models is None:
        models = default_model_set(lambda f: report(0.08 * f))
    if utilities is None:
        utilities = default_utilities(cfg.precompression_pct)
    report(0.1)
    # Serialised once: every controller of every participant is built from the same
    # documents (the factory takes them inline).
    models = ModelSet.from_json(models.to_json())
    cohort = Cohort(cfg, models_version=str(models.version),
                    utilities_version=str(getattr(utilities, "version", "")))
    docs = (models.to_json(), utilities.to_json())
    if processes > 1 and cfg.participants > 2:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        cohort.participants.append(simulate_participant(cfg, 0, models, utilities, docs))
        report(0.1 + 0.9 / cfg.participants)
        rest = range(1, cfg.participants)
        chunk = max(1, min(4, len(rest) // (4 * processes)))
        with ProcessPoolExecutor(max_workers=processes,
                                 mp_context=mp.get_context(_start_method()),
                                 initializer=_pool_init, initargs=(cfg, *docs)) as pool:
            for j, result in enumerate(pool.map(_pool_participant, rest, chunksize=chunk),
                                       start=2):
                cohort.participants.append(result)
                report(0.1 + 0.9 * j / cfg.participants)
        return cohort
    for j in range(cfg.participants):
        cohort.participants.append(simulate_participant(cfg, j, models, utilities, docs))
        report(0.1 + 0.9 * (j + 1) / cfg.participants)
    return cohort
