"""A virtual personalisation study: population models, personal models and learned
priors compared on the same virtual wearers (docs/personalisation.md, "Virtual
evidence").

Design, stated:
- Participants are the cohort engine's (`CohortConfig.participant_seed`: seed S,
  participant j), one cohort of `participants` per seed.
- **Population models, leave-one-out.** Every participant records the paper's data
  collection (one squat sequence and one stoop sequence: 10 squats, 5 stoops to each
  side, segmented by the lift segmentation and labelled by the ground truth at each
  segment's peak). Participant j's population set is fitted from the data collection
  of every *other* participant of the same cohort, never from j's own.
- **Personal demonstrations.** A demonstration block in j's session, at the same
  donning as j's trials: the data-collection squat sequence plus a second stoop
  sequence, so up to 10 demonstrations of each motion; the first `n` of each motion
  make the personal set for `n`.
- **Personal models.** MAP adaptation of j's population set (`adapt_model_set`, the
  module's default `tau`) for every `n`, and the participant-only PPCA fit
  (`fit_participant_model_set`) where `n` reaches its minimum (3).
- **Learned priors.** From a previous working day of j's (`working_day`, a stairs-heavy
  day): every confirmed motion feeds the count-based Dirichlet update with forgetting
  (the module's default pseudo-counts and forgetting), projected onto the safe set of
  the utility table (`PriorBounds.project`). The same priors are used in the lab and on
  the evaluation day.
- **Lab evaluation.** The paper's evaluation script once per controller (repetition =
  the controller's position, as in the cohort engine), the *same* recording replayed
  under every condition, so each participant's change is the effect of the models or
  priors on the same movement. A real study would run each condition as a new trial;
  its intervals would be wider.
- **Stairs-heavy day.** Another working day of j's (not the one the priors came from),
  replayed through the UMC with j's population models, equal against learned priors.
- Controllers: those that use motion models (UMC, E-UMC); the PEC has none, so no
  condition here changes it. One utility set for everyone (the simulated reference
  dataset at the cohort's precompression).
- Recordings are the cohort engine's: the simulated hip angles plus each donning's
  encoder offset and drift (no quantisation), for speed.

Repetition numbers keep every realisation apart: trials use 0 and 1, the
demonstration block 100-102, the working days 200 (priors) and 201 (evaluation). A
script realised with the same participant and repetition would repeat the same draws.
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
from controller.evaluation.cohort import (
    MAX_PARTICIPANTS,
    SEED_BASE,
    calibrated,
    cohort_controllers,
    default_utilities,
    recording_metrics,
    trial_recording,
)
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import lifts_from_truth, trials_from_truth
from controller.evaluation.study import evaluate_recording
from controller.evaluation.working_day import (
    DEFAULT_BLOCKS,
    confirmed_motions,
    day_metrics,
    day_recording,
)
from controller.intent.learned_priors import (
    DEFAULT_FORGETTING,
    DEFAULT_PSEUDO_COUNT,
    LearnedPriors,
    learn_from_confirmed,
)
from controller.intent.motion_model import ModelSet, fit_model_set
from controller.intent.personal_models import (
    DEFAULT_TAU,
    MIN_PARTICIPANT_DEMOS,
    TooFewDemonstrationsError,
    adapt_model_set,
    fit_participant_model_set,
)
from controller.intent.prior_safety import PriorBounds
from controller.intent.segmentation import segment_lifts
from controller.runner.replay import AngleRecording, replay_columns
from controller.sim.participant import VirtualParticipant
from controller.tick_record import MODEL_NAMES

FloatArray = np.ndarray
LAB_SCRIPT = "paper-evaluation"
#: (script, repetition): the data collection (also the first part of the block) ...
POOL_RECORDINGS: tuple[tuple[str, int], ...] = (("squat-sequence", 100),
                                                ("stoop-sequence", 101))
#: ... and the rest of the personal demonstration block.
EXTRA_RECORDINGS: tuple[tuple[str, int], ...] = (("stoop-sequence", 102),)
MAX_DEMOS = 10
PRIOR_DAY_REPETITION = 200
EVAL_DAY_REPETITION = 201
POPULATION = "population"


def model_controllers() -> tuple[str, ...]:
    """The planned controllers that use motion models (the ones models can change)."""
    return tuple(c for c in cohort_controllers() if needs_models(c))


def map_condition(n: int) -> str:
    """Name of the MAP-adapted condition with n demonstrations per motion."""
    return f"map-{n}"


def own_condition(n: int) -> str:
    """Name of the participant-only condition with n demonstrations per motion."""
    return f"own-{n}"


def with_priors(condition: str) -> str:
    """Name of a condition run with the participant's learned priors."""
    return f"{condition}+priors"


@dataclass(frozen=True)
class PersonalisationConfig:
    """What to simulate. `tau`, `pseudo_count` and `forgetting` default to the modules'
    own defaults and are not tuned here."""

    participants: int = 40
    seeds: tuple[int, ...] = (1, 2, 3)
    controllers: tuple[str, ...] = field(default_factory=model_controllers)
    demo_counts: tuple[int, ...] = (0, 3, 5, 10)
    #: The personal (MAP) set that is also run with learned priors.
    priors_with: int = 10
    tau: float = DEFAULT_TAU
    pseudo_count: float = DEFAULT_PSEUDO_COUNT
    forgetting: float = DEFAULT_FORGETTING
    day_blocks: int = DEFAULT_BLOCKS
    precompression_pct: float = 25.0

    def __post_init__(self) -> None:
        if not 3 <= self.participants <= MAX_PARTICIPANTS:
            raise ValueError(f"participants: must be within 3..{MAX_PARTICIPANTS} (each "
                             f"population set needs two others), got {self.participants}")
        if not self.seeds or len(set(self.seeds)) != len(self.seeds) or not all(
                0 <= s <= 99_999 for s in self.seeds):
            raise ValueError(f"seeds: distinct, within 0..99999, got {list(self.seeds)}")
        allowed = model_controllers()
        if not self.controllers or any(c not in allowed for c in self.controllers) or len(
                set(self.controllers)) != len(self.controllers):
            raise ValueError(f"controllers: each at most once, from {','.join(allowed)} "
                             f"(those with motion models), got {','.join(self.controllers)}")
        if not self.demo_counts or any(not 0 <= n <= MAX_DEMOS for n in self.demo_counts) \
                or list(self.demo_counts) != sorted(set(self.demo_counts)):
            raise ValueError(f"demo_counts: increasing, within 0..{MAX_DEMOS}, got "
                             f"{list(self.demo_counts)}")
        if self.priors_with not in self.demo_counts:
            raise ValueError(f"priors_with: must be one of demo_counts "
                             f"{list(self.demo_counts)}, got {self.priors_with}")
        if not (math.isfinite(self.tau) and self.tau > 0):
            raise ValueError(f"tau: must be positive, got {self.tau}")
        if not (math.isfinite(self.pseudo_count) and self.pseudo_count > 0):
            raise ValueError(f"pseudo_count: must be positive, got {self.pseudo_count}")
        if not 0.0 < self.forgetting <= 1.0:
            raise ValueError(f"forgetting: must be in (0, 1], got {self.forgetting}")
        if not 1 <= self.day_blocks <= 100:
            raise ValueError(f"day_blocks: must be within 1..100, got {self.day_blocks}")
        if not 0.0 <= self.precompression_pct <= 100.0:
            raise ValueError("precompression_pct: must be within 0..100")

    def participant_seed(self, seed: int, j: int) -> int:
        """Simulator seed of participant j of the cohort with `seed` (the cohort
        engine's numbering, so the same people as `exostudy cohort --seed`)."""
        return SEED_BASE + seed * MAX_PARTICIPANTS + j

    def conditions(self) -> tuple[str, ...]:
        """Lab conditions in table order."""
        out = [POPULATION, *(map_condition(n) for n in self.demo_counts),
               *(own_condition(n) for n in self.demo_counts if n >= MIN_PARTICIPANT_DEMOS),
               with_priors(POPULATION), with_priors(map_condition(self.priors_with))]
        return tuple(out)

    def settings(self) -> ControllerConfig:
        """The controllers' settings (the paper's rates)."""
        return ControllerConfig(precompression_pct=self.precompression_pct)


Demos = dict[str, list[FloatArray]]


@dataclass(frozen=True)
class ParticipantData:
    """What one participant brings before any controller runs."""

    seed: int
    index: int
    participant_seed: int
    pool: Demos  # the data collection, for the others' population sets
    personal: Demos  # the whole demonstration block, in order
    motions: tuple[str, ...]  # confirmed motions of the prior working day


@dataclass(frozen=True)
class ParticipantOutcome:
    """One participant's results: lab metrics per controller and condition, the
    stairs-day metrics per priors ("equal", "learned"), the learned priors."""

    seed: int
    index: int
    participant_seed: int
    lab: dict[str, dict[str, dict[str, float]]]
    day: dict[str, dict[str, float]]
    priors: LearnedPriors
    personal_available: dict[str, int]
    own_refused: tuple[str, ...] = ()


def _labelled(rec: AngleRecording, label: str) -> tuple[Demos, dict[str, list[str]]]:
    segs: Demos = {m: [] for m in MODEL_NAMES}
    ids: dict[str, list[str]] = {m: [] for m in MODEL_NAMES}
    assert rec.activity is not None
    for i, seg in enumerate(segment_lifts(rec.t, rec.q)):
        kind = rec.activity[seg.peak]
        if kind in MODEL_NAMES:
            segs[kind].append(rec.q[seg.start:seg.end + 1].copy())
            ids[kind].append(f"{label}:segment={i}")
    return segs, ids


def collect_participant(cfg: PersonalisationConfig, seed: int, j: int) -> ParticipantData:
    """Participant j's data collection, demonstration block and prior working day."""
    ps = cfg.participant_seed(seed, j)
    p = VirtualParticipant.from_seed(ps)
    pool: Demos = {m: [] for m in MODEL_NAMES}
    personal: Demos = {m: [] for m in MODEL_NAMES}
    for script, rep in (*POOL_RECORDINGS, *EXTRA_RECORDINGS):
        segs, _ = _labelled(trial_recording(p, ps, script, rep), script)
        for m in MODEL_NAMES:
            personal[m] += segs[m]
            if (script, rep) in POOL_RECORDINGS:
                pool[m] += segs[m]
    day = day_recording(p, ps, cfg.day_blocks, PRIOR_DAY_REPETITION)
    assert day.activity is not None
    return ParticipantData(seed, j, ps, pool, personal, tuple(confirmed_motions(day.activity)))


def population_set(data: Sequence[ParticipantData], j: int) -> ModelSet:
    """Participant j's population set: fitted from every other participant's data
    collection (leave-one-out)."""
    demos: Demos = {m: [] for m in MODEL_NAMES}
    ids: dict[str, list[str]] = {m: [] for m in MODEL_NAMES}
    for d in data:
        if d.index == j:
            continue
        for m in MODEL_NAMES:
            demos[m] += d.pool[m]
            ids[m] += [f"sim:seed={d.participant_seed}:{m}:{i}" for i in range(len(d.pool[m]))]
    me = next(d for d in data if d.index == j)
    return fit_model_set(demos, demo_ids=ids, version=f"loo-{me.seed}-{j + 1}",
                         meta={"source": "virtual personalisation study, leave-one-out",
                               "left_out": me.participant_seed})


def learned_priors(cfg: PersonalisationConfig, data: ParticipantData,
                   bounds: PriorBounds) -> LearnedPriors:
    """The participant's priors from their prior working day's confirmed motions."""
    return learn_from_confirmed(
        list(data.motions), bounds,
        sources=[f"sim:seed={data.participant_seed}:day={PRIOR_DAY_REPETITION}:motion={i}"
                 for i in range(len(data.motions))],
        pseudo_counts=(cfg.pseudo_count,) * 4, forgetting=cfg.forgetting,
        version=f"learned-{data.participant_seed}",
        meta={"participant_seed": data.participant_seed, "source": "working day"})


def _run(name: str, settings: ControllerConfig, rec: AngleRecording, models: ModelSet,
         models_doc: dict[str, Any], utilities_doc: dict[str, Any],
         priors: LearnedPriors | None, precompression_pct: float) -> TickData:
    s = settings
    if registry.needs_calibration(name):
        start = models.start_posture()
        s, _ = calibrated(settings, rec, start)
    spec = ControllerSpec(name, s, models=models_doc, utilities=utilities_doc, priors=priors)
    return TickData.of(replay_columns(rec, make_from_spec(spec), precompression_pct))


def personal_sets(cfg: PersonalisationConfig, population: ModelSet, data: ParticipantData
                  ) -> tuple[dict[str, ModelSet], tuple[str, ...]]:
    """Every model set of the lab conditions (without priors), and the participant-only
    conditions that were refused (too few demonstrations segmented)."""
    label = f"P{data.participant_seed}"
    sets: dict[str, ModelSet] = {POPULATION: population}
    refused: list[str] = []
    for n in cfg.demo_counts:
        demos = {m: data.personal[m][:n] for m in MODEL_NAMES}
        sets[map_condition(n)] = adapt_model_set(population, demos, tau=cfg.tau,
                                                 participant=label)
        if n >= MIN_PARTICIPANT_DEMOS:
            try:
                sets[own_condition(n)] = fit_participant_model_set(demos, participant=label)
            except (TooFewDemonstrationsError, ValueError):
                refused.append(own_condition(n))
    return sets, tuple(refused)


def simulate_participant(cfg: PersonalisationConfig, data: ParticipantData,
                         population: ModelSet, utilities: UtilitySet) -> ParticipantOutcome:
    """Every lab condition and both stairs-day conditions for one participant."""
    p = VirtualParticipant.from_seed(data.participant_seed)
    settings = cfg.settings()
    udoc = utilities.to_json()
    priors = learned_priors(cfg, data, PriorBounds.for_table(utilities.table.values))
    sets, refused = personal_sets(cfg, population, data)
    docs = {k: v.to_json() for k, v in sets.items()}
    runs: list[tuple[str, str, LearnedPriors | None]] = [(k, k, None) for k in sets]
    runs += [(with_priors(POPULATION), POPULATION, priors),
             (with_priors(map_condition(cfg.priors_with)), map_condition(cfg.priors_with),
              priors)]
    label = f"V{data.seed}-{data.index + 1:03d}"
    lab: dict[str, dict[str, dict[str, float]]] = {}
    for i, name in enumerate(cfg.controllers):
        rec = trial_recording(p, data.participant_seed, LAB_SCRIPT, repetition=i)
        lab[name] = {}
        for cond, set_name, pr in runs:
            cols = _run(name, settings, rec, sets[set_name], docs[set_name], udoc, pr,
                        cfg.precompression_pct)
            ev = evaluate_recording(cols, label, name, lifts_from_truth(cols),
                                    trials_from_truth(cols))
            lab[name][cond] = recording_metrics(ev)
        for cond in refused:
            lab[name][cond] = {}
    day_rec = day_recording(p, data.participant_seed, cfg.day_blocks, EVAL_DAY_REPETITION)
    day = {}
    for which, pr in (("equal", None), ("learned", priors)):
        cols = _run("umc", settings, day_rec, population, docs[POPULATION], udoc, pr,
                    cfg.precompression_pct)
        day[which] = day_metrics(cols, label, "umc").metrics
    return ParticipantOutcome(data.seed, data.index, data.participant_seed, lab, day, priors,
                              {m: len(data.personal[m]) for m in MODEL_NAMES}, refused)


@dataclass
class PersonalisationStudy:
    """The configuration and every participant's outcome (seed, then index order)."""

    config: PersonalisationConfig
    outcomes: list[ParticipantOutcome] = field(default_factory=list)
    utilities_version: str = ""
    seconds: float = 0.0


_WORKER: tuple[PersonalisationConfig, UtilitySet] | None = None


def _init(cfg: PersonalisationConfig, utilities_doc: dict[str, Any]) -> None:
    global _WORKER
    _WORKER = (cfg, UtilitySet.from_json(utilities_doc))


def _collect_task(key: tuple[int, int]) -> ParticipantData:
    assert _WORKER is not None, "worker process not initialised"
    return collect_participant(_WORKER[0], *key)


def _simulate_task(args: tuple[ParticipantData, dict[str, Any]]) -> ParticipantOutcome:
    assert _WORKER is not None, "worker process not initialised"
    cfg, utilities = _WORKER
    return simulate_participant(cfg, args[0], ModelSet.from_json(args[1]), utilities)


def simulate_study(cfg: PersonalisationConfig, utilities: UtilitySet | None = None,
                   progress: Callable[[float], None] | None = None,
                   processes: int = 1) -> PersonalisationStudy:
    """The whole study. `processes` > 1 spreads participants over that many processes;
    the result is the same as with one."""
    import time

    t0 = time.perf_counter()
    report = progress or (lambda _f: None)
    utilities = utilities or default_utilities(cfg.precompression_pct)
    udoc = utilities.to_json()
    study = PersonalisationStudy(cfg, utilities_version=str(getattr(utilities, "version", "")))
    total = len(cfg.seeds) * cfg.participants
    _init(cfg, udoc)
    pool = None
    if processes > 1:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(max_workers=processes, mp_context=mp.get_context("spawn"),
                                   initializer=_init, initargs=(cfg, udoc))
    try:
        for s_i, seed in enumerate(cfg.seeds):
            keys = [(seed, j) for j in range(cfg.participants)]
            data = list(pool.map(_collect_task, keys)) if pool else [
                _collect_task(k) for k in keys]
            args = [(d, population_set(data, d.index).to_json()) for d in data]
            results = pool.map(_simulate_task, args) if pool else map(_simulate_task, args)
            for j, r in enumerate(results):
                study.outcomes.append(r)
                report((s_i * cfg.participants + j + 1) / total)
    finally:
        if pool is not None:
            pool.shutdown()
    study.seconds = time.perf_counter() - t0
    return study
