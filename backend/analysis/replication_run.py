"""`exostudy replicate`: the paper's claims checked one by one over several virtual
studies; this module runs or reads the seeds and the extra measures, and hands the
result to `backend.analysis.replication_report` to write.

How a run is made (`backend.analysis.replication_config.ReplicationConfig`):

- **Seeds.** Each seed is a whole virtual study of the paper's protocol (8 evaluation
  participants, 3 of them also with the E-UMC, 6 data-collection participants whose
  demonstrations fit that seed's motion models), at the paper's rates. Every claim's
  number is a mean over a seed's participants; the interval is over seeds
  (`controller.evaluation.verdicts`).
- **Engines.** `cohort` (default) replays the protocol through the controllers in this
  process (`controller.evaluation.paper_protocol.protocol_seed`: the cohort engine's
  trial replay, the live loop's tick code, no server), the same virtual participants
  and data-collection seeds as the virtual study; 20 seeds take minutes. `study` (when
  asked) runs `exostudy virtual-study` for each seed in its own process, one after the
  other, into `OUT/seeds/seed-<S>/`: the whole live chain (server, worker, simulated
  device), about 100 minutes for 20 seeds. A seed whose folder already holds a
  finished study (`summary.json` next to `study.db`) is read, not run again, so an
  interrupted or extended run reuses its seeds, and two runs never write one folder at
  once (a folder being written has no `summary.json`; it is left alone and reported).
  `--from-db` reads existing `study.db` files instead of running anything.
- **Beyond the seeds.** The method checks (utilities, value iteration, chi-square tail,
  actuator) are deterministic; the donning-offset regression uses one larger virtual
  cohort (`offset_participants`); the stair kinematics are measured on the simulator
  (`controller.evaluation.paper_protocol`); the personalisation section (beyond the
  paper) runs one virtual personalisation cohort of `personalisation_participants`
  (`controller.evaluation.personalisation`, seed `first_seed`; 0 skips it).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from functools import cache, partial
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from sqlalchemy import text

from backend.analysis import tick_queries
from backend.analysis.replication_config import (
    Replication,
    ReplicationConfig,
    SeedResult,
)
from backend.analysis.replication_report import timeline_figure, write
from backend.db.engine import make_engine
from controller.decision.utility_function import UtilitySet
from controller.evaluation import muscle_report
from controller.evaluation.cohort import default_utilities
from controller.evaluation.columns import TickData
from controller.evaluation.figures import peak_torque_figure
from controller.evaluation.ground_truth import ground_truth
from controller.evaluation.method_figures import (
    actuator_figure,
    chi_square_figure,
    motion_models_figure,
    offset_figure,
    stairs_figure,
    utility_difference_figure,
)
from controller.evaluation.paper_claims import judge_all
from controller.evaluation.paper_protocol import (
    PAPER_PRECOMPRESSION,
    PUBLISHED_STAIRS,
    SeedTrials,
    measure_seed,
    method_checks,
    offset_regression,
    protocol_seed,
    stair_kinematics,
)
from controller.evaluation.personalisation import PersonalisationConfig, simulate_study
from controller.evaluation.personalisation_report import (
    analysis_json,
    curve_figure,
    day_table,
    lab_changes,
    participants_table,
)
from controller.evaluation.rendering import render_figure
from controller.evaluation.study import evaluate_recording
from controller.evaluation.tables import FalsePositiveTable, PerformanceTable
from controller.intent.motion_model import ModelSet
from controller.private_files import make_private_dir, open_private, private_folder

#: One seed's evaluated trials with their ticks, and the model and utility sets used.
SeedLoad = tuple[SeedTrials, ModelSet | None, UtilitySet | None]
#: Tick fields a claim reads (the rest of a stored trial is not loaded).
_FIELDS = ("t", "controller_ran", "action", "lock_left", "lock_right", "post_squat",
           "post_stoop_left", "post_stoop_right", "post_other", "s_curr_squat",
           "s_curr_stoop_left", "s_curr_stoop_right", "torque_left", "torque_right",
           "truth_activity", "truth_lift", "truth_progress", "q_left", "q_right")


def study_seed_folder(out: Path, seed: int) -> Path:
    """Where seed `seed` of the `study` engine lives."""
    return out / "seeds" / f"seed-{seed}"


def run_study_seed(cfg: ReplicationConfig, seed: int, log: Callable[[str], None]) -> Path:
    """The seed's `study.db`, running `exostudy virtual-study` in a child process unless
    a finished one is there already."""
    folder = study_seed_folder(cfg.out, seed)
    db = folder / "study.db"
    if (folder / "summary.json").is_file() and db.is_file():
        log(f"seed {seed}: reusing {db}")
        return db
    if folder.exists():
        raise ValueError(f"seed {seed}: {folder} holds an unfinished virtual study (no "
                         "summary.json): another run may be writing it; remove the folder "
                         "to run that seed again")
    private_folder(folder.parent)
    cmd = [sys.executable, "-m", "backend.cli", "virtual-study", "--seed", str(seed),
           "--participants", str(cfg.participants), "--eumc", str(cfg.eumc),
           "--data-participants", str(cfg.data_participants), "--rates", "paper-rates",
           "--no-model-evaluation", "--out", str(folder)]
    log(f"seed {seed}: running the virtual study ({' '.join(cmd[2:])})")
    # The virtual study writes a database of (simulated) participants: umask 077 makes
    # whatever the child creates its owner's alone, like the report around it.
    with open_private(cfg.out / f"seed-{seed}.log") as logf:
        code = subprocess.call(cmd, stdout=logf, stderr=subprocess.STDOUT,
                               env={**os.environ, "PYTHONUNBUFFERED": "1"}, umask=0o077)
    if code != 0 or not (folder / "summary.json").is_file():
        # Kept for inspection, out of the way of the next attempt.
        if folder.exists():
            folder.rename(folder.with_name(
                f"{folder.name}.failed-{time.strftime('%Y%m%d-%H%M%S')}"))
        raise RuntimeError(f"seed {seed}: the virtual study failed (exit {code}); see "
                           f"{cfg.out / f'seed-{seed}.log'}")
    return db


def _document(doc: object) -> dict[str, object]:
    return doc if isinstance(doc, dict) else json.loads(str(doc))


def read_study_db(path: Path) -> SeedLoad:
    """Every completed trial of the first study in a `study.db` (the paper-rates study
    of a virtual study) with its ticks, and the model and utility sets it used.

    Plain SQL on the stable columns, so a file written by an older or newer schema
    still reads."""
    engine = make_engine(f"sqlite:///{Path(path).resolve()}")
    out: SeedTrials = []
    models: ModelSet | None = None
    utilities: UtilitySet | None = None
    try:
        with engine.connect() as c:
            study = c.execute(text("SELECT min(id) FROM studies")).scalar()
            if study is None:
                raise ValueError(f"{path}: holds no study")
            rows = c.execute(text(
                "SELECT t.id, t.controller, t.task, t.run_id, t.model_set_id, "
                "t.utility_set_id, p.code FROM trials t "
                "JOIN study_sessions s ON t.session_id = s.id "
                "JOIN participants p ON s.participant_id = p.id "
                "WHERE p.study_id = :sid AND t.status = 'completed' "
                "AND t.run_id IS NOT NULL ORDER BY p.id, s.id, t.planned_order"),
                {"sid": study}).all()
            ms_id = next((r[4] for r in rows if r[4] is not None), None)
            us_id = next((r[5] for r in rows if r[5] is not None), None)
            if ms_id is not None:
                models = ModelSet.from_json(_document(c.execute(
                    text("SELECT document FROM model_sets WHERE id = :i"),
                    {"i": ms_id}).scalar()))
            if us_id is not None:
                utilities = UtilitySet.from_json(_document(c.execute(
                    text("SELECT document FROM utility_sets WHERE id = :i"),
                    {"i": us_id}).scalar()))
        for _tid, ctl, task, run_id, _ms, _us, code in rows:
            cols = TickData.of(tick_queries.columns(engine, run_id, fields=_FIELDS))
            truth = ground_truth(cols, task)
            out.append((cols, evaluate_recording(cols, code, ctl, truth.lifts, truth.gait)))
    finally:
        engine.dispose()
    return out, models, utilities


def cohort_seed(cfg: ReplicationConfig, seed: int,
                utilities: UtilitySet | None = None) -> SeedLoad:
    """One seed of the `cohort` engine (`paper_protocol.protocol_seed`); `utilities`:
    the paper's set (`default_utilities(PAPER_PRECOMPRESSION)`), the same for every
    seed, if the caller has it."""
    return protocol_seed(seed, cfg.participants, cfg.eumc, cfg.data_participants, utilities)


def _figure(fig: Figure) -> tuple[bytes, bytes]:
    r = render_figure(fig)
    return r.png, r.svg


def _first_seed(rep: Replication, trials: SeedTrials, models: ModelSet | None) -> None:
    """The first seed's tables and figures (the paper's layout)."""
    evs = [e for _c, e in trials]
    rep.first_tables["performance"] = PerformanceTable.from_evaluations(
        evs, ("umc", "eumc")).wide()
    rep.first_tables["false_positives"] = FalsePositiveTable.from_evaluations(
        evs, ("pec", "umc", "eumc")).wide()
    rep.figures["peak_torques"] = _figure(peak_torque_figure(evs, ("pec", "umc", "eumc")))
    tl = timeline_figure(trials, models)
    if tl is not None:
        rep.figures["controller_output"] = tl
    if models is not None:
        rep.figures["motion_models"] = _figure(motion_models_figure(models))


def _sources(cfg: ReplicationConfig, log: Callable[[str], None],
             paper_utilities: Callable[[], UtilitySet]
             ) -> list[tuple[str, Callable[[], SeedLoad]]]:
    def from_study(seed: int) -> SeedLoad:
        return read_study_db(run_study_seed(cfg, seed, log))

    last: dict[Path, SeedLoad] = {}

    def from_db(path: Path) -> SeedLoad:
        # A file given again right after itself is read once (the one before is kept
        # until the next file, no longer).
        key = path.resolve()
        if key not in last:
            last.clear()
            last[key] = read_study_db(path)
        return last[key]

    if cfg.from_db:
        return [(str(p), partial(from_db, Path(p))) for p in cfg.from_db]
    if cfg.engine == "study":
        return [(f"seed {s}", partial(from_study, s)) for s in cfg.seed_list()]
    def from_cohort(seed: int) -> SeedLoad:
        return cohort_seed(cfg, seed, paper_utilities())

    return [(f"seed {s}", partial(from_cohort, s)) for s in cfg.seed_list()]


def personalisation_step(cfg: ReplicationConfig, utilities: UtilitySet,
                         log: Callable[[str], None]
                         ) -> tuple[dict[str, Any], tuple[bytes, bytes]]:
    """The personalisation section's study (one cohort, the claims' utility set) as its
    `personalisation.json` document and the demonstration-count curve (PNG, SVG)."""
    pcfg = PersonalisationConfig(participants=cfg.personalisation_participants,
                                 seeds=(cfg.first_seed,))
    log(f"personalisation: {pcfg.participants} virtual participants, seed {cfg.first_seed}")
    study = simulate_study(pcfg, utilities)
    doc = analysis_json(study)
    # Every participant's values beside the changes, so each change can be checked.
    doc["per_participant"] = {
        name: [dict(zip(t.header, row, strict=True)) for row in t.rows]
        for name, t in (("lab", participants_table(study)), ("day", day_table(study)))}
    return doc, curve_figure(study, lab_changes(study))


def run(cfg: ReplicationConfig, log: Callable[[str], None] = print,
        progress: Callable[[float], None] | None = None) -> Replication:
    """Run or read every seed, judge every claim and write the report into `cfg.out`;
    `progress(fraction)` after each seed and each later phase."""
    report = progress or (lambda _f: None)
    t_start = time.monotonic()
    make_private_dir(cfg.out)  # new: 0700; a folder the user gave keeps its mode
    rep = Replication(cfg)
    first_models: ModelSet | None = None
    utilities: UtilitySet | None = None
    # The paper's utility set is the same for every seed and the offset cohort:
    # computed once, when first needed.
    paper_utilities = cache(partial(default_utilities, PAPER_PRECOMPRESSION))
    sources = _sources(cfg, log, paper_utilities)
    t0 = time.monotonic()
    steps = len(sources) + 2 + (1 if cfg.personalisation_participants else 0)
    for i, (label, load) in enumerate(sources):
        t1 = time.monotonic()
        trials, models, us = load()
        rep.seeds.append(SeedResult(label, measure_seed(trials, models),
                                    "from-db" if cfg.from_db else cfg.engine,
                                    round(time.monotonic() - t1, 1)))
        if i == 0:
            first_models, utilities = models, us
            _first_seed(rep, trials, models)
        log(f"{label}: measured in {time.monotonic() - t1:.0f} s")
        del trials
        report((i + 1) / steps)
    rep.phases["seeds"] = round(time.monotonic() - t0, 1)
    if utilities is None:
        utilities = paper_utilities()
    t0 = time.monotonic()
    rep.checks = method_checks(utilities)
    rep.figures["utilities"] = _figure(utility_difference_figure(utilities.table.values))
    rep.figures["actuator"] = _figure(actuator_figure())
    rep.figures["chi_square"] = _figure(chi_square_figure())
    rep.offsets = offset_regression(cfg.offset_participants, cfg.first_seed, log,
                                    paper_utilities())
    for name in ("both", "difference"):
        o = rep.offsets[name]
        label = ("mean |offset| of both hips (deg)" if name == "both"
                 else "|left - right offset| (deg)")
        rep.figures[f"offsets_{name}"] = _figure(offset_figure(
            np.array(o["x"]), np.array(rep.offsets["gain"]), o["slope"], o["intercept"],
            label))
    rep.phases["offsets"] = round(time.monotonic() - t0, 1)
    rep.sections["muscle_activity"] = muscle_report.replication_section(
        rep.figures, cfg.participants, cfg.first_seed, first_models, utilities, log)
    report((len(sources) + 1) / steps)
    if cfg.personalisation_participants:
        t0 = time.monotonic()
        rep.personalisation, rep.figures["personalisation_curve"] = personalisation_step(
            cfg, utilities, log)
        rep.phases["personalisation"] = round(time.monotonic() - t0, 1)
        report((steps - 1) / steps)
    t0 = time.monotonic()
    rep.stairs = stair_kinematics(cfg.stair_participants, cfg.first_seed)
    cyc = {k: np.array(v) for k, v in rep.stairs.pop("cycles").items()}
    rep.figures["stairs"] = _figure(stairs_figure(
        cyc, {k: v["hip_rom_deg"] for k, v in PUBLISHED_STAIRS.items()}))
    rep.phases["stairs"] = round(time.monotonic() - t0, 1)
    rep.claims = judge_all([s.measures for s in rep.seeds], rep.checks)
    rep.wall_s = round(time.monotonic() - t_start, 1)
    write(rep)
    report(1.0)
    return rep
