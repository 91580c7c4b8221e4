"""`exostudy replicate`: the paper's claims checked one by one over several virtual
studies, written as one self-contained HTML report.

How a run is made (`ReplicationConfig`):

- **Seeds.** Each seed is a whole virtual study of the paper's protocol (8 evaluation
  participants, 3 of them also with the E-UMC, 6 data-collection participants whose
  demonstrations fit that seed's motion models), at the paper's rates. Every claim's
  number is a mean over a seed's participants; the interval is over seeds
  (`controller.evaluation.verdicts`).
- **Engines.** `study` (default) runs `exostudy virtual-study` for each seed in its own
  process, one after the other, into `OUT/seeds/seed-<S>/`: the whole live chain
  (server, worker, simulated device). A seed whose folder already holds a finished
  study (`summary.json` next to `study.db`) is read, not run again, so an interrupted
  or extended run reuses its seeds, and two runs never write one folder at once (a
  folder being written has no `summary.json`; it is left alone and reported).
  `cohort` replays the same protocol through the controllers in this process
  (`controller.runner.replay`, the live loop's tick code, no server), the same virtual
  participants and data-collection seeds; it is faster and does not depend on the
  server. `--from-db` reads existing `study.db` files instead of running anything.
- **Beyond the seeds.** The method checks (utilities, value iteration, chi-square tail,
  actuator) are deterministic; the donning-offset regression uses one larger virtual
  cohort (`offset_participants`); the stair kinematics are measured on the simulator.

Outputs in `OUT`: `report.html` (figures embedded as data URIs, no network access
needed), `figures/*.png|svg`, `replication.json` (every number) and `replication.md`
(the claim table).
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Literal

import numpy as np
from scipy import stats
from sqlalchemy import text

from controller.decision.utility_function import UtilitySet
from controller.evaluation import muscle_report
from controller.evaluation.columns import TickData
from controller.evaluation.figures import peak_torque_figure
from controller.evaluation.lifts import lifts_from_truth, trials_from_truth
from controller.evaluation.method_figures import (
    PRECOMPRESSIONS,
    actuator_figure,
    chi_square_figure,
    motion_models_figure,
    offset_figure,
    stairs_figure,
    utility_difference_figure,
)
from controller.evaluation.rendering import render_figure
from controller.evaluation.replication import (
    DEFAULT_SEEDS,
    PAPER_FALSE_POSITIVES,
    PAPER_PERFORMANCE,
    RULE_TEXT,
    ClaimResult,
    difference_dict,
    judge_all,
    seed_measures,
    trial_data,
    verdict_counts,
)
from controller.evaluation.study import RecordingEvaluation, evaluate_recording
from controller.evaluation.tables import FalsePositiveTable, PerformanceTable
from controller.evaluation.timeline import controller_output_figure
from controller.evaluation.verdicts import t_interval
from controller.intent.motion_model import ModelSet
from controller.private_files import (
    make_private_dir,
    open_private,
    private_folder,
    write_private,
)

Engine = Literal["study", "cohort"]
#: One seed's evaluated trials with their ticks, and the model and utility sets used.
SeedLoad = tuple[list[tuple[TickData, RecordingEvaluation]], ModelSet | None,
                 UtilitySet | None]
#: Tick fields a claim reads (the rest of a stored trial is not loaded).
_FIELDS = ("t", "controller_ran", "action", "lock_left", "lock_right", "post_squat",
           "post_stoop_left", "post_stoop_right", "post_other", "s_curr_squat",
           "s_curr_stoop_left", "s_curr_stoop_right", "torque_left", "torque_right",
           "truth_activity", "truth_lift", "truth_progress", "q_left", "q_right")
#: The paper's protocol (data about the paper's study, not a property of the
#: controllers): every participant used the UMC and the PEC in this order, the first
#: `eumc` participants also the E-UMC, whose trials the paper's timeline figure shows.
PAPER_CONTROLLERS = ("umc", "pec")
PAPER_EXTRA = "eumc"
#: Published stair kinematics compared with the simulation (see docs/replication.md).
PUBLISHED_STAIRS: dict[str, dict[str, Any]] = {
    "stairs_up": {"hip_rom_deg": (55.0, 70.0), "cadence_spm": (85.0, 100.0),
                  "source": "Riener et al. 2002 (Gait Posture 15:32-44); Protopapadaki et "
                            "al. 2007 (Clin Biomech 22:203-210)"},
    "stairs_down": {"hip_rom_deg": (25.0, 40.0), "cadence_spm": (90.0, 110.0),
                    "source": "Riener et al. 2002; Protopapadaki et al. 2007"},
}


@dataclass(frozen=True)
class ReplicationConfig:
    """What to run; see the module docstring."""

    out: Path
    seeds: int = DEFAULT_SEEDS
    first_seed: int = 1
    engine: Engine = "study"
    from_db: tuple[Path, ...] = ()
    participants: int = 8
    eumc: int = 3
    data_participants: int = 6
    offset_participants: int = 60
    stair_participants: int = 20

    def __post_init__(self) -> None:
        if not self.from_db and not 2 <= self.seeds <= 50:
            raise ValueError(f"seeds: need 2..50 for an interval, got {self.seeds}")
        if self.engine not in ("study", "cohort"):
            raise ValueError(f"engine: choose study or cohort, got {self.engine!r}")
        if not 2 <= self.participants <= 40:
            raise ValueError("participants: must be within 2..40")
        if not 1 <= self.eumc <= self.participants:
            raise ValueError(f"eumc: must be within 1..{self.participants}")
        if not 2 <= self.data_participants <= 12:
            raise ValueError("data_participants: must be within 2..12")
        if not 4 <= self.offset_participants <= 2000:
            raise ValueError("offset_participants: must be within 4..2000")
        if not 2 <= self.stair_participants <= 500:
            raise ValueError("stair_participants: must be within 2..500")
        for p in self.from_db:
            if not Path(p).is_file():
                raise FileNotFoundError(f"--from-db: no database file at {p}")

    def seed_list(self) -> list[int]:
        """The seeds run (none with `from_db`)."""
        return [] if self.from_db else list(range(self.first_seed,
                                                  self.first_seed + self.seeds))


@dataclass
class SeedResult:
    """One seed's measures and where they came from."""

    label: str
    measures: dict[str, float]
    source: str
    wall_s: float = 0.0


@dataclass
class Replication:
    """Everything the report shows."""

    config: ReplicationConfig
    seeds: list[SeedResult] = field(default_factory=list)
    claims: list[ClaimResult] = field(default_factory=list)
    checks: dict[str, float] = field(default_factory=dict)
    offsets: dict[str, Any] = field(default_factory=dict)
    stairs: dict[str, Any] = field(default_factory=dict)
    first_tables: dict[str, str] = field(default_factory=dict)
    figures: dict[str, tuple[bytes, bytes]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    phases: dict[str, float] = field(default_factory=dict)


# --------------------------------------------------------------------------- one seed


def _online_end(models: ModelSet | None) -> float:
    if models is None:
        return 0.5
    m = models.ordered()[0]
    return (m.online_n - 1) / (m.mean.shape[0] - 1)


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


def _sqlite_url(path: Path) -> str:
    return f"sqlite:///{Path(path).resolve()}"


def read_study_db(path: Path) -> SeedLoad:
    """Every completed trial of the first study in a `study.db` (the paper-rates study
    of a virtual study) with its ticks, and the model and utility sets it used.

    Plain SQL on the stable columns, so a file written by an older or newer schema
    still reads."""
    from backend.analysis import tick_queries
    from backend.analysis.results import ground_truth
    from backend.db.engine import make_engine

    engine = make_engine(_sqlite_url(path))
    out: list[tuple[TickData, RecordingEvaluation]] = []
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
                doc = c.execute(text("SELECT document FROM model_sets WHERE id = :i"),
                                {"i": ms_id}).scalar()
                models = ModelSet.from_json(doc if isinstance(doc, dict) else json.loads(str(doc)))
            if us_id is not None:
                doc = c.execute(text("SELECT document FROM utility_sets WHERE id = :i"),
                                {"i": us_id}).scalar()
                utilities = UtilitySet.from_json(doc if isinstance(doc, dict)
                                                 else json.loads(str(doc)))
        for _tid, ctl, task, run_id, _ms, _us, code in rows:
            cols_d = tick_queries.columns(engine, run_id, fields=_FIELDS)
            cols = TickData.of(cols_d)
            truth = ground_truth(cols, task)
            ev = evaluate_recording(cols, code, ctl, truth.lifts, truth.gait)
            out.append((cols, ev))
    finally:
        engine.dispose()
    return out, models, utilities


def cohort_seed(cfg: ReplicationConfig, seed: int
                ) -> tuple[list[tuple[TickData, RecordingEvaluation]], ModelSet, UtilitySet]:
    """The protocol of one seed replayed through the controllers in this process: the
    virtual study's participants (`seed*100 + 1 + j`) and data-collection seeds
    (`seed*100 + 50 + i`), each controller on its own repetition of the script."""
    from controller.config import ControllerConfig
    from controller.controllers import registry
    from controller.controllers.factory import make_from_spec, needs_models
    from controller.controllers.spec import ControllerSpec
    from controller.evaluation.cohort import calibrated, default_utilities, trial_recording
    from controller.runner.replay import replay_columns
    from controller.sim.demonstrations import simulated_model_set
    from controller.sim.participant import VirtualParticipant

    models = simulated_model_set(seeds=[seed * 100 + 50 + i
                                        for i in range(cfg.data_participants)])
    utilities = default_utilities(25.0)
    docs = (models.to_json(), utilities.to_json())
    settings = ControllerConfig(precompression_pct=25.0)
    start = models.start_posture()
    out: list[tuple[TickData, RecordingEvaluation]] = []
    for j in range(cfg.participants):
        pseed = seed * 100 + 1 + j
        p = VirtualParticipant.from_seed(pseed)
        ctls = [*PAPER_CONTROLLERS, *([PAPER_EXTRA] if j < cfg.eumc else [])]
        for i, name in enumerate(ctls):
            rec = trial_recording(p, pseed, "paper-evaluation", repetition=i)
            s = (calibrated(settings, rec, start)[0] if registry.needs_calibration(name)
                 else settings)
            sets = needs_models(name)
            spec = ControllerSpec(name, s, models=docs[0] if sets else None,
                                  utilities=docs[1] if sets else None)
            cols = TickData.of(replay_columns(rec, make_from_spec(spec), 25.0))
            ev = evaluate_recording(cols, f"P{j + 1:02d}", name, lifts_from_truth(cols),
                                    trials_from_truth(cols))
            out.append((cols, ev))
    return out, models, utilities


def _models_separation(models: ModelSet) -> float:
    """Smaller stoop |L - R| minus squat |L - R| (deg) at the end of the online part."""
    by = {m.name: m for m in models.ordered()}
    k = by["squat"].online_n - 1

    def gap(name: str) -> float:
        mu = np.degrees(by[name].mean[k])
        return float(abs(mu[0] - mu[1]))

    return min(gap("stoop_left"), gap("stoop_right")) - gap("squat")


def _timeline(trials: Sequence[tuple[TickData, RecordingEvaluation]],
              models: ModelSet | None) -> tuple[bytes, bytes] | None:
    """The paper's five-panel figure: the first five asymmetric stoops of participant 3
    with the E-UMC (or the first E-UMC participant if there is no third)."""
    eumc = [(c, e) for c, e in trials if e.controller == PAPER_EXTRA]
    if not eumc:
        return None
    cols, ev = next(((c, e) for c, e in eumc if e.participant.endswith("03")), eumc[-1])
    stoops = [o.lift for o in ev.lifts if o.lift.kind != "squat"][:5]
    if not stoops:
        return None
    a, b = max(stoops[0].start - 100, 0), min(stoops[-1].end + 100, len(cols))
    fig = controller_output_figure(cols, a, b, models, [o.lift for o in ev.lifts],
                                   title=f"E-UMC, participant {ev.participant}: first five "
                                   "asymmetric stoops")
    r = render_figure(fig)
    return r.png, r.svg


def measure_seed(label: str, trials: Sequence[tuple[TickData, RecordingEvaluation]],
                 models: ModelSet | None) -> dict[str, float]:
    """`seed_measures` of one seed plus its model-set measure."""
    end = _online_end(models)
    m = seed_measures([trial_data(c, e, end) for c, e in trials])
    if models is not None:
        m["models_separation_deg"] = _models_separation(models)
    return m


# --------------------------------------------------------------------------- extras


def method_checks(utilities: UtilitySet) -> dict[str, float]:
    """The deterministic claims: utilities, value iteration, chi-square, actuator."""
    from controller.intent.posteriors import likelihood
    from controller.lowlevel.actuator import maccepa_torque
    from controller.tick_record import CATEGORY_NAMES, Action

    v = utilities.table.values
    gaps = []
    for kind, other in (("stoop_left", Action.LOCK_RIGHT), ("stoop_right", Action.LOCK_LEFT)):
        j = CATEGORY_NAMES.index(kind)
        gaps.append(float(v[int(Action.NO_LOCK) - 1, j, 0] - v[int(other) - 1, j, 0]))
    gap = utilities.meta.get("assumption_gap", {})
    scale = float(np.abs(v[:, :3]).max()) or 1.0
    vi = max((float(x) for x in gap.values()), default=math.nan) / scale
    # Within each curve's compression limit: torque grows with deflection, and at a
    # deflection every curve reaches, with precompression.
    from controller.lowlevel.actuator import max_deflection

    tops = [max_deflection(p) for p in PRECOMPRESSIONS]
    bad = n = 0
    for p, top in zip(PRECOMPRESSIONS, tops, strict=True):
        tau = np.asarray(maccepa_torque(np.linspace(0.0, top, 60), p), dtype=np.float64)
        bad += int((np.diff(tau) < -1e-12).sum())
        n += tau.size - 1
    usable = [p for p, top in zip(PRECOMPRESSIONS, tops, strict=True) if top > 0]
    common = np.linspace(0.0, min(t for t in tops if t > 0), 60)
    curves = np.array([np.asarray(maccepa_torque(common, p), dtype=np.float64)
                       for p in usable])
    bad += int((np.diff(curves, axis=0) < -1e-12).sum())
    n += curves.shape[1] * (curves.shape[0] - 1)
    return {"utility_stoop_gap": min(gaps), "value_iteration_gap": vi,
            "chi_square_tail": float(likelihood(7.5, 3)), "actuator_violations": bad / n}


def offset_regression(cfg: ReplicationConfig, log: Callable[[str], None]) -> dict[str, Any]:
    """UMC minus E-UMC correct decisions (per 20 lifts, the paper's counting rule)
    against the donning offset, over a virtual cohort; ordinary least squares."""
    from controller.evaluation.cohort import CohortConfig, simulate_cohort

    ccfg = CohortConfig(participants=cfg.offset_participants, seed=cfg.first_seed,
                        controllers=("umc", "eumc"))
    log(f"offsets: simulating a cohort of {ccfg.participants}")
    cohort = simulate_cohort(ccfg)
    off = np.array([p.body["offset_deg"] for p in cohort.participants], dtype=np.float64)
    gain = (cohort.values("umc", "correct_pct") - cohort.values("eumc", "correct_pct")) / 5.0
    out: dict[str, Any] = {"participants": ccfg.participants, "seed": ccfg.seed,
                           "offset_deg": off.tolist(), "gain": gain.tolist(),
                           }
    iv = t_interval(gain)
    out["mean_gain"] = {"mean": iv.mean, "low": iv.low, "high": iv.high}
    for name, x in (("both", np.abs(off).mean(axis=1)), ("difference", np.abs(off[:, 0]
                                                                             - off[:, 1]))):
        ok = np.isfinite(x) & np.isfinite(gain)
        fit = stats.linregress(x[ok], gain[ok])
        tcrit = float(stats.t.ppf(0.975, int(ok.sum()) - 2))
        out[name] = {"slope": float(fit.slope), "intercept": float(fit.intercept),
                     "stderr": float(fit.stderr), "low": float(fit.slope - tcrit * fit.stderr),
                     "high": float(fit.slope + tcrit * fit.stderr), "r": float(fit.rvalue),
                     "p": float(fit.pvalue), "n": int(ok.sum()), "x": x[ok].tolist()}
    return out


def stair_kinematics(n: int, first_seed: int = 1) -> dict[str, Any]:
    """Hip flexion range, peak, cadence and leg asymmetry of the simulated stair ascent
    and descent, per participant, from the `stairs` script (steady strides only: the
    0.8 s cross-fades at the ends of each piece are left out)."""
    from scipy.signal import find_peaks

    from controller.sim.participant import VirtualParticipant
    from controller.sim.scripts import get_script, realise

    script = get_script("stairs")
    res: dict[str, dict[str, list[float]]] = {}
    cycles: dict[str, list[np.ndarray]] = {}
    for j in range(n):
        seed = 2_000_000 + first_seed * 1000 + j
        p = VirtualParticipant.from_seed(seed)
        tr = realise(script, p, seed)
        act = tr.activity_names()
        deg = np.degrees(tr.theta)
        for kind in ("stairs_up", "stairs_down"):
            idx = np.flatnonzero(act == kind)
            if idx.size < 200:
                continue
            idx = idx[80:-80]  # away from the cross-fades
            q = deg[idx]
            r = res.setdefault(kind, {k: [] for k in ("rom_l", "rom_r", "peak_l", "peak_r",
                                                       "cadence", "rom_diff")})
            r["rom_l"].append(float(np.ptp(q[:, 0])))
            r["rom_r"].append(float(np.ptp(q[:, 1])))
            stand = p.stand_flexion_deg
            r["peak_l"].append(float(q[:, 0].max() - stand[0]))
            r["peak_r"].append(float(q[:, 1].max() - stand[1]))
            r["rom_diff"].append(abs(r["rom_l"][-1] - r["rom_r"][-1]))
            pk, _ = find_peaks(q[:, 0], distance=60)
            if pk.size >= 2:
                stride = float(np.median(np.diff(pk))) * 0.01
                r["cadence"].append(120.0 / stride)
                for a, b in zip(pk[:-1], pk[1:], strict=True):
                    seg = q[a:b + 1, 0]
                    cycles.setdefault(kind, []).append(
                        np.interp(np.linspace(0, 1, 101), np.linspace(0, 1, seg.size), seg))
    summary: dict[str, Any] = {"participants": n}
    for kind, r in res.items():
        summary[kind] = {k: {"mean": float(np.mean(v)), "sd": float(np.std(v, ddof=1)),
                             "min": float(np.min(v)), "max": float(np.max(v))}
                         for k, v in r.items() if v}
        summary[kind]["published"] = PUBLISHED_STAIRS[kind]
    summary["cycles"] = {k: np.array(v).tolist() for k, v in cycles.items()}
    return summary


# --------------------------------------------------------------------------- the run


def run(cfg: ReplicationConfig, log: Callable[[str], None] = print,
        progress: Callable[[float], None] | None = None) -> Replication:
    """Run or read every seed, judge every claim and write the report into `cfg.out`;
    `progress(fraction)` after each seed and each later phase."""
    report = progress or (lambda _f: None)
    t_start = time.monotonic()
    make_private_dir(cfg.out)  # new: 0700; a folder the user gave keeps its mode
    rep = Replication(cfg)
    first: tuple[list[tuple[TickData, RecordingEvaluation]], ModelSet | None] | None = None
    utilities: UtilitySet | None = None
    def from_study(seed: int) -> SeedLoad:
        return read_study_db(run_study_seed(cfg, seed, log))

    sources: list[tuple[str, Callable[[], SeedLoad]]]
    if cfg.from_db:
        sources = [(str(p), partial(read_study_db, Path(p))) for p in cfg.from_db]
    elif cfg.engine == "study":
        sources = [(f"seed {s}", partial(from_study, s)) for s in cfg.seed_list()]
    else:
        sources = [(f"seed {s}", partial(cohort_seed, cfg, s)) for s in cfg.seed_list()]
    t0 = time.monotonic()
    steps = len(sources) + 2
    for i, (label, load) in enumerate(sources):
        t1 = time.monotonic()
        trials, models, us = load()
        m = measure_seed(label, trials, models)
        rep.seeds.append(SeedResult(label, m, "from-db" if cfg.from_db else cfg.engine,
                                    round(time.monotonic() - t1, 1)))
        if first is None:
            first = (trials, models)
            utilities = us
            evs = [e for _c, e in trials]
            rep.first_tables["performance"] = PerformanceTable.from_evaluations(
                evs, ("umc", "eumc")).to_markdown()
            rep.first_tables["false_positives"] = FalsePositiveTable.from_evaluations(
                evs, ("pec", "umc", "eumc")).to_markdown()
            pt = render_figure(peak_torque_figure(evs, ("pec", "umc", "eumc")))
            rep.figures["peak_torques"] = (pt.png, pt.svg)
            tl = _timeline(trials, models)
            if tl is not None:
                rep.figures["controller_output"] = tl
            if models is not None:
                mm = render_figure(motion_models_figure(models))
                rep.figures["motion_models"] = (mm.png, mm.svg)
        log(f"{label}: measured in {time.monotonic() - t1:.0f} s")
        del trials
        report((i + 1) / steps)
    rep.phases["seeds"] = round(time.monotonic() - t0, 1)
    if utilities is None:
        from controller.evaluation.cohort import default_utilities

        utilities = default_utilities(25.0)
    t0 = time.monotonic()
    rep.checks = method_checks(utilities)
    for name, fig in (("utilities", utility_difference_figure(utilities.table.values)),
                      ("actuator", actuator_figure()), ("chi_square", chi_square_figure())):
        r = render_figure(fig)
        rep.figures[name] = (r.png, r.svg)
    rep.offsets = offset_regression(cfg, log)
    for name in ("both", "difference"):
        o = rep.offsets[name]
        label = ("mean |offset| of both hips (deg)" if name == "both"
                 else "|left - right offset| (deg)")
        r = render_figure(offset_figure(np.array(o["x"]), np.array(rep.offsets["gain"]),
                                        o["slope"], o["intercept"], label))
        rep.figures[f"offsets_{name}"] = (r.png, r.svg)
    rep.phases["offsets"] = round(time.monotonic() - t0, 1)
    rep.first_tables["muscle_activity"] = muscle_report.replication_section(
        rep.figures, cfg.participants, cfg.first_seed, first[1] if first else None,
        utilities, log)
    report((steps - 1) / steps)
    t0 = time.monotonic()
    rep.stairs = stair_kinematics(cfg.stair_participants, cfg.first_seed)
    cyc = {k: np.array(v) for k, v in rep.stairs.pop("cycles").items()}
    r = render_figure(stairs_figure(cyc, {k: v["hip_rom_deg"]
                                          for k, v in PUBLISHED_STAIRS.items()}))
    rep.figures["stairs"] = (r.png, r.svg)
    rep.phases["stairs"] = round(time.monotonic() - t0, 1)
    rep.claims = judge_all([s.measures for s in rep.seeds], rep.checks)
    rep.wall_s = round(time.monotonic() - t_start, 1)
    write(rep)
    report(1.0)
    return rep


# --------------------------------------------------------------------------- writing


def _interval_dict(c: ClaimResult) -> dict[str, Any]:
    iv = c.interval
    return {"n": iv.n, "mean": iv.mean, "low": iv.low, "high": iv.high, "sd": iv.sd}


def _jsonable(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, Path):
        return str(x)
    return x


def claims_markdown(rep: Replication) -> str:
    """The per-claim table as Markdown."""
    lines = ["| claim | source | paper | virtual mean [95 % CI] | verdict | why |",
             "| --- | --- | --- | --- | --- | --- |"]
    for c in rep.claims:
        paper = "" if not math.isfinite(c.claim.paper) else f"{c.claim.paper:.4g}"
        if c.claim.kind == "ordinal":
            sign = ">" if c.claim.direction > 0 else "<"
            paper = f"{sign} {c.claim.threshold:g}" + (f" (paper {paper})" if paper else "")
        lines.append(f"| {c.claim.key} | {c.claim.source} | {paper} | "
                     f"{c.interval.text('.3g')} {c.claim.unit} | {c.verdict_text()} | "
                     f"{c.reason} |")
    return "\n".join(lines) + "\n"


def _paper_table_html() -> str:
    head = "".join(f"<th>{p}</th>" for p in ("1", "2", "3", "4", "5", "6", "7", "8"))
    rows = []
    for (ctl, metric, g), row in PAPER_PERFORMANCE.items():
        cells = "".join(f"<td>{row.get(p, '/')}</td>" for p in "12345678")
        rows.append(f"<tr><td>{ctl.upper()}</td><td>{metric}</td><td>{g}</td>{cells}</tr>")
    perf = (f"<table><tr><th>controller</th><th>metric</th><th>motion</th>{head}</tr>"
            + "".join(rows) + "</table>")
    rows = []
    for (ctl, g), row in PAPER_FALSE_POSITIVES.items():
        cells = "".join(f"<td>{row.get(p, '/')}</td>" for p in "12345678")
        rows.append(f"<tr><td>{ctl.upper()}</td><td>{g}</td>{cells}</tr>")
    fp = (f"<table><tr><th>controller</th><th>trial</th>{head}</tr>" + "".join(rows)
          + "</table>")
    return (f"<h3>Table \"Intent estimation and Decision Performance for (E-)UMC\" "
            f"(paper, transcribed; PEC rows from its text)</h3>{perf}"
            f"<h3>Table \"Number of false positive lock signals\" (paper, transcribed)</h3>"
            f"{fp}")


def _md_table_html(md: str) -> str:
    """A Markdown table written by `Table.to_markdown` as HTML (no dependency)."""
    out, in_table = [], False
    for line in md.splitlines():
        if line.startswith("|") and set(line.replace("|", "").strip()) <= {"-", " "}:
            continue
        if line.startswith("|"):
            cells = [html.escape(c.strip()) for c in line.strip("|").split(" | ")]
            tag = "th" if not in_table else "td"
            out.append("<tr>" + "".join(f"<{tag}>{c}</{tag}>" for c in cells) + "</tr>")
            if not in_table:
                out.insert(len(out) - 1, "<table>")
            in_table = True
        else:
            if in_table:
                out.append("</table>")
                in_table = False
            if line.strip():
                out.append(f"<p>{html.escape(line.strip('*'))}</p>")
    if in_table:
        out.append("</table>")
    return "\n".join(out)


_CSS = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;"
        "line-height:1.4}table{border-collapse:collapse;margin:0.5em 0;font-size:0.85em}"
        "td,th{border:1px solid #bbb;padding:3px 6px;vertical-align:top}"
        ".reproduced,.equivalent{background:#dff0d8}.differs{background:#f8d7da}"
        ".inconclusive{background:#fff3cd}.unstable td:nth-child(6){font-style:italic}"
        ".not-simulated{background:#eee}img{max-width:100%}figure{margin:1em 0}")


def report_html(rep: Replication) -> str:
    """The self-contained HTML report."""
    cfg = rep.config
    if cfg.from_db:
        how = f"{len(rep.seeds)} existing study databases"
    else:
        how = (f"{len(rep.seeds)} seeds ({cfg.first_seed}..{cfg.first_seed + cfg.seeds - 1}), "
               f"engine '{cfg.engine}', {cfg.participants} participants per seed "
               f"({cfg.eumc} also with the E-UMC), {cfg.data_participants} data-collection "
               "participants per seed")
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>ExoStudy replication"
             f"</title><style>{_CSS}</style></head><body>",
             "<h1>The paper replicated claim by claim</h1>",
             f"<p>{html.escape(how)}. Run time {rep.wall_s:.0f} s ("
             + ", ".join(f"{k} {v:.0f} s" for k, v in rep.phases.items()) + ").</p>",
             f"<p>Verdicts: {html.escape(verdict_counts(rep.claims))}.</p>",
             f"<h2>Rule</h2><p>{html.escape(RULE_TEXT)} Counts "
             "are per 10 lifts of a kind, decisions by the paper's counting rule (squat: "
             "both sides commanded in the first half, in one decision or two; stoop: the "
             "first lock decision is the supporting side).</p>",
             "<h2>Claims</h2><table><tr><th>claim</th><th>source</th><th>paper</th>"
             "<th>virtual mean [95 % CI]</th><th>seeds</th><th>verdict</th><th>why</th></tr>"]
    for c in rep.claims:
        paper = "" if not math.isfinite(c.claim.paper) else f"{c.claim.paper:.4g}"
        if c.claim.kind == "ordinal":
            sign = "&gt;" if c.claim.direction > 0 else "&lt;"
            paper = f"{sign} {c.claim.threshold:g}" + (f" (paper {paper})" if paper else "")
        seeds = ", ".join("n/a" if not math.isfinite(v) else f"{v:.3g}" for v in c.seeds)
        cls = c.verdict.value.replace(" ", "-") + (" unstable" if c.unstable else "")
        parts.append(
            f"<tr class='{cls}'><td><b>{html.escape(c.claim.key)}</b><br>"
            f"{html.escape(c.claim.statement)}</td><td>{html.escape(c.claim.source)}</td>"
            f"<td>{paper}</td><td>{html.escape(c.interval.text('.3g'))} "
            f"{html.escape(c.claim.unit)}</td><td>{seeds}</td><td>{c.verdict_text()}</td>"
            f"<td>{html.escape(c.reason)}</td></tr>")
    parts.append("</table>")
    parts.append("<h2>The paper's tables</h2>" + _paper_table_html())
    for name, md in rep.first_tables.items():
        parts.append(f"<h3>Virtual, first seed: {name.replace('_', ' ')}</h3>"
                     + _md_table_html(md))
    o = rep.offsets
    if o:
        parts.append("<h2>Donning offsets and calibration</h2><p>A virtual cohort of "
                     f"{o['participants']} participants (seed {o['seed']}) with the UMC and "
                     "the calibrated E-UMC. Per participant, UMC minus E-UMC correct "
                     "decisions per 20 lifts: mean "
                     f"{o['mean_gain']['mean']:.2f} [{o['mean_gain']['low']:.2f}, "
                     f"{o['mean_gain']['high']:.2f}]. Ordinary least squares "
                     "(scipy.stats.linregress), slope with its 95 % t interval:</p><ul>")
        for name in ("both", "difference"):
            r = o[name]
            what = "mean |offset| of both hips" if name == "both" else "|left - right offset|"
            parts.append(f"<li>{what}: "
                         f"slope {r['slope']:.3f} [{r['low']:.3f}, {r['high']:.3f}] per deg, "
                         f"r = {r['r']:.2f}, p = {r['p']:.3g}, n = {r['n']}</li>")
        parts.append("</ul>")
    st = rep.stairs
    if st:
        parts.append("<h2>Stairs</h2><p>Simulated stair ascent and descent "
                     f"({st['participants']} virtual participants, steady strides) against "
                     "published kinematics.</p><table><tr><th></th><th>hip ROM left (deg)"
                     "</th><th>hip ROM right</th><th>|L-R| ROM</th><th>peak flexion above "
                     "standing</th><th>cadence (steps/min)</th><th>published ROM</th>"
                     "<th>published cadence</th><th>source</th></tr>")
        for kind in ("stairs_up", "stairs_down"):
            k = st.get(kind)
            if not k:
                continue

            def ms(name: str, k: dict[str, Any] = k) -> str:
                v = k.get(name)
                return "" if v is None else f"{v['mean']:.1f} &plusmn; {v['sd']:.1f}"

            pub = k["published"]
            parts.append(f"<tr><td>{kind}</td><td>{ms('rom_l')}</td><td>{ms('rom_r')}</td>"
                         f"<td>{ms('rom_diff')}</td><td>{ms('peak_l')}</td>"
                         f"<td>{ms('cadence')}</td><td>{pub['hip_rom_deg'][0]:g}-"
                         f"{pub['hip_rom_deg'][1]:g}</td><td>{pub['cadence_spm'][0]:g}-"
                         f"{pub['cadence_spm'][1]:g}</td><td>{html.escape(pub['source'])}</td>"
                         "</tr>")
        parts.append("</table>")
        fav = [(c, [s.measures.get(f"umc.stair_favoured.{c}", math.nan) for s in rep.seeds])
               for c in ("squat", "stoop_left", "stoop_right", "other")]
        parts.append("<p>Which category the UMC's posteriors favour during simulated stair "
                     "walking (share of the ticks where it ran; mean [95 % CI] over seeds): "
                     + "; ".join(f"{c} {t_interval(v).text('.2f')}" for c, v in fav)
                     + ".</p>")
    parts.append("<h2>Figures</h2>")
    captions = {
        "peak_torques": "Peak left and right exoskeleton torque per lift (first seed), PEC, "
                        "UMC, E-UMC (paper figure \"peak torques\").",
        "controller_output": "Controller output, E-UMC, first five asymmetric stoops "
                             "(paper's five-panel figure).",
        "motion_models": "Motion models with 95 % regions (first seed).",
        "utilities": "Utility of each action minus no lock, per lifting motion.",
        "actuator": "Actuator torque against deflection at several precompressions.",
        "chi_square": "Chi-square density, 6 degrees of freedom, D = 7.5.",
        "offsets_both": "UMC minus E-UMC correct decisions against the mean donning offset.",
        "offsets_difference": "The same against the difference of the two hips' offsets.",
        "stairs": "Simulated hip flexion over the stair cycle against the published range.",
    }
    for name, (png, _svg) in rep.figures.items():
        data = base64.b64encode(png).decode("ascii")
        parts.append(f"<figure><img alt='{name}' src='data:image/png;base64,{data}'>"
                     f"<figcaption>{html.escape(captions.get(name, name))} "
                     f"(<a href='figures/{name}.svg'>SVG</a>)</figcaption></figure>")
    if rep.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>"
                                                     for n in rep.notes) + "</ul>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write(rep: Replication) -> list[Path]:
    """Write the report, the figures, the JSON and the Markdown claim table: folders
    0700 and files 0600 whatever the umask (the report sits in the private run folder,
    and a copy of it must not be the one thing others can read)."""
    out = rep.config.out
    make_private_dir(out)
    figs = private_folder(out / "figures")
    paths = []
    for name, (png, svg) in rep.figures.items():
        for ext, data in (("png", png), ("svg", svg)):
            p = figs / f"{name}.{ext}"
            write_private(p, data)
            paths.append(p)
    doc = {"config": {k: _jsonable(v) for k, v in rep.config.__dict__.items()},
           "wall_s": rep.wall_s, "phases": rep.phases,
           "seeds": [{"label": s.label, "source": s.source, "wall_s": s.wall_s,
                      "measures": _jsonable(s.measures)} for s in rep.seeds],
           "claims": [{"key": c.claim.key, "source": c.claim.source,
                       "statement": c.claim.statement, "kind": c.claim.kind,
                       "paper": _jsonable(c.claim.paper), "unit": c.claim.unit,
                       "interval": _jsonable(_interval_dict(c)),
                       "seeds": _jsonable(list(c.seeds)), "verdict": c.verdict.value,
                       "reason": c.reason, "paper_values": list(c.claim.paper_values),
                       "margin": _jsonable(c.claim.margin),
                       "difference": _jsonable(difference_dict(c.difference)),
                       "halves": None if c.halves is None else [v.value for v in c.halves],
                       "unstable": c.unstable} for c in rep.claims],
           "checks": _jsonable(rep.checks),
           "offsets": _jsonable({k: v for k, v in rep.offsets.items()
                                 if k not in ("offset_deg", "gain")}),
           "stairs": _jsonable(rep.stairs), "notes": rep.notes}
    for name, body in (("replication.json", json.dumps(doc, indent=1)),
                       ("replication.md", claims_markdown(rep)),
                       ("report.html", report_html(rep))):
        p = out / name
        write_private(p, body)
        paths.append(p)
    return paths
