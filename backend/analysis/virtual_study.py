"""The paper's protocol on virtual participants, through the live server.

`exostudy virtual-study --participants 8 --seed S --out DIR` runs a whole study the
way an experimenter would, over the REST API of a real server (`create_app` on
`DIR/study.db`), with the real worker process, control loop and in-process simulated
exoskeleton, only faster than real time (`device_speed`). Nothing is shortcut: the
demonstrations are recorded ticks, the models and utilities are the API's background
jobs, the trials are started and stopped through the API and evaluated from their
stored ticks. That is the point: it checks the chain a live study uses, end to end.

Protocol (paper, "User study set-up"), and the choices made here:

- Data collection: `data_participants` other virtual participants each record the
  `squat-sequence` and the `stoop-sequence` (10 kg box); the segments are labelled
  from the simulation's truth (`POST /api/recordings/{id}/segment`); one model set is
  fitted from all of them and the utilities are computed from the simulated
  reference human dataset at 25 % precompression.
- Evaluation: `participants` virtual participants evaluate UMC and PEC in the
  counterbalanced order the trial plan gives, and the first `eumc` of them the E-UMC
  as well (calibrated standing still, retried while the wearer moves). A trial is one
  repetition of the `paper-evaluation` script, which holds the four tasks of the paper
  (squat sequence, stoop sequence, 10 m walk and back, stairs up and down, 5 kg box)
  with its pauses; the tables split it into lifts and gait trials by the simulation's
  truth. One script per trial rather than one trial per task keeps the trial count (and
  the per-trial overhead of starting, stopping and evaluating) at the paper's number of
  controller conditions; changing the simulated wearer or task swaps the simulator
  inside the running worker (a new run, no process start).
- Rates: two studies with the same virtual participants (same seeds, same order):
  "paper rates" (UMC 10 Hz, PEC 100 Hz, E-UMC 100/10 Hz) and "100 Hz" (every
  controller at 100 Hz, `{"rate_hz": 100}` at trial start). Two studies rather than two
  sessions keep each study's results endpoint to one rate setting. A trial takes its
  sets from its participant's study, so each study records the same demonstrations
  (same seeds) and fits its own model and utility sets; the outputs name the first's.
- A trial runs for one repetition of the script plus `margin_s` of device time: a
  timed trial (`duration_s`), which the worker ends by itself after that many samples,
  so neither a worker that falls behind the requested speed nor a server that is slow
  to notice changes what a trial holds; the tick rate actually achieved and any
  device-time gaps are reported.
- Questionnaires are left out: a virtual participant has no opinion, and invented
  answers would only look like data. The outputs say so.
- Muscle activity (`emg`, `--emg`; off by default: the paper's protocol alone, several
  times faster): the first rate setting's study also plans the two baseline conditions
  (springs free, no exoskeleton), counterbalanced and blinded with the controllers,
  each one repetition of the `lift-evaluation` script (the lifts of the paper's
  evaluation: baselines are measured in lifts only). The simulator publishes the
  wearer's EMG on LSL as a 16-channel 2 kHz amplifier (`controller.sim.emg_amplifier`);
  each participant's session of that study subscribes to the stream by its source id
  (this process is the server, so the id names this study's simulator and no other on
  the machine; 12 muscles by the study's montage, 4 spare inputs ignored) for its
  trials and records it through the server's inlet into the EMG store, and the results
  read it back (`backend.emg.muscle_results`), normalised to the task peak
  (a virtual participant performs no MVC). The simulation runs faster than real time,
  so the stream's timestamps are closer together than 2 kHz: every recording carries
  the `rate_mismatch` flag, which says exactly that; samples are processed at the
  amplifier's nominal rate. A sped-up trial produces EMG faster than the server's
  inlet stores it; LSL buffers the rest, and after each such trial the simulator runs
  at real time until the inlet has caught up (`virtual_study_emg.drain_emg`), so
  nothing overflows.

The parts, a module each: `virtual_study_config` (the settings, the protocol's
constants, the report), `virtual_study_driver` (the REST calls and the waits on the
worker), `virtual_study_collection` (the data-collection phase), `virtual_study_trials`
(the evaluation phase), `virtual_study_emg` (the EMG study's stream), and
`virtual_study_outputs` (the files written); this module creates the server and runs
the phases in order.
"""

from __future__ import annotations

import json
import os
import secrets
import time
from collections.abc import Callable

from backend.analysis.virtual_study_collection import collect
from backend.analysis.virtual_study_config import (
    DATASET_INFO,
    LSL_CONFIG,
    QUESTIONNAIRE_NOTE,
    RATE_SETTINGS,
    TrialTiming,
    VirtualStudyConfig,
    VirtualStudyError,
    VirtualStudyReport,
)
from backend.analysis.virtual_study_driver import Driver, ok, script_duration_s
from backend.analysis.virtual_study_emg import setup_emg
from backend.analysis.virtual_study_outputs import lopo_markdown, readme, write_outputs
from backend.analysis.virtual_study_speeds import COLLECTION_SPEED, DEFAULT_SPEED
from backend.analysis.virtual_study_trials import evaluate
from backend.core.config import Settings
from backend.core.resources import version
from backend.db import migrate
from backend.db.engine import make_engine, make_session_factory
from backend.live.local_server import serving
from backend.main import create_app
from backend.study import accounts

__all__ = ["COLLECTION_SPEED", "DATASET_INFO", "DEFAULT_SPEED", "QUESTIONNAIRE_NOTE",
           "RATE_SETTINGS", "TrialTiming", "VirtualStudyConfig", "VirtualStudyError",
           "VirtualStudyReport", "lopo_markdown", "run", "script_duration_s"]


def run(cfg: VirtualStudyConfig, log: Callable[[str], None] = print) -> VirtualStudyReport:
    """Run the virtual study into `cfg.out` (which must not hold a `study.db` yet)."""
    t_start = time.monotonic()
    # liblsl reads this at its first call: the simulated amplifier and its inlet find
    # each other on this machine only (no network, no other computer's streams).
    cfg.out.mkdir(parents=True, exist_ok=True)
    if cfg.emg and "LSLAPICFG" not in os.environ:
        (cfg.out / "lsl_api.cfg").write_text(LSL_CONFIG)
        os.environ["LSLAPICFG"] = str((cfg.out / "lsl_api.cfg").resolve())
    db_path = cfg.out.resolve() / "study.db"
    if db_path.exists():
        raise ValueError(f"out: {db_path} exists; choose an empty folder")
    url = f"sqlite:///{db_path}"
    migrate.upgrade(url)
    password = secrets.token_urlsafe(24)
    engine = make_engine(url)
    with make_session_factory(engine)() as s:
        accounts.create_user(s, "virtual-study", password)
        s.commit()
    settings = Settings(  # type: ignore[call-arg]
        database_url=url, start_worker=True, device_kind="sim", device_speed=cfg.speed,
        device_seed=cfg.data_seed(0), device_script=cfg.data_scripts[0],
        device_emg_lsl=cfg.emg, _env_file=None)
    report = VirtualStudyReport(out=cfg.out)
    report.notes.append(QUESTIONNAIRE_NOTE)
    try:
        app = create_app(settings)
        # A real server on a loopback port and plain HTTP, as any script of a user's.
        with serving(app) as client:
            client.token = ok(client.post("/api/auth/token", json={
                "username": "virtual-study", "password": password}))["access_token"]
            d = Driver(client, cfg.speed, log)
            studies: dict[str, int] = {}
            for label in cfg.rates:
                name = (f"Virtual study seed {cfg.seed} ({label}) "
                        f"{time.strftime('%Y-%m-%d %H:%M:%S')}")
                desc = ("Virtual participants through the live server; every controller at "
                        "100 Hz" if RATE_SETTINGS[label] else
                        "Virtual participants through the live server; the paper's rates")
                studies[label] = ok(client.post("/api/studies", json={
                    "name": name, "description": desc, "dataset_info": DATASET_INFO}),
                    201)["id"]
            report.studies = studies
            if cfg.emg:
                setup_emg(d, studies[cfg.rates[0]])
            first = next(iter(studies.values()))
            # A trial takes its model and utility sets from its participant's study, and
            # a model set is fitted from its own study's segments: every rate setting's
            # study records the same demonstrations (same seeds, so the same fits) and
            # fits its own sets.
            collection_s = fitting_s = 0.0
            sets: dict[int, tuple[int, int]] = {}
            for study_id in studies.values():
                t0 = time.monotonic()
                segment_ids = collect(d, cfg, study_id)
                collection_s += time.monotonic() - t0
                t0 = time.monotonic()
                # No recording runs while the sets are fitted: `collect` left the
                # simulated wearer at real time, or its sped-up ticks (stored, never
                # read) would compete with the jobs for the cores (at 400x the phase took
                # 5-14 s instead of 2-5 s). Each trial sets its own wearer and speed.
                ms = ok(client.post(f"/api/studies/{study_id}/model-sets", json={
                    "name": "virtual data collection", "segment_ids": segment_ids}), 202)
                us = ok(client.post(f"/api/studies/{study_id}/utility-sets", json={
                    "name": "simulated reference, 25 %", "precompression_pct": 25}), 202)
                d.job(ms["job_id"])
                d.job(us["job_id"])
                sets[study_id] = (ms["id"], us["id"])
                fitting_s += time.monotonic() - t0
                log(f"models {ms['id']} and utilities {us['id']} ready")
            report.model_set_id, report.utility_set_id = sets[first]
            report.phases["data collection"] = collection_s
            report.phases["models and utilities"] = fitting_s
            t0 = time.monotonic()
            evaluate(d, cfg, studies, sets, report, app.state.engine)
            report.phases["evaluation"] = time.monotonic() - t0
            t0 = time.monotonic()
            # `evaluate` left the simulated wearer at real time: no sped-up ticks nobody
            # reads while the outputs are computed.
            write_outputs(d, cfg, studies, *sets[first], report)
            report.phases["tables and figures"] = time.monotonic() - t0
    finally:
        engine.dispose()
    report.wall_s = time.monotonic() - t_start
    report.phases = {k: round(v, 1) for k, v in report.phases.items()}
    report.wall_s = round(report.wall_s, 1)
    (cfg.out / "README.md").write_text(readme(cfg, report))
    report.files.append("README.md")
    (cfg.out / "summary.json").write_text(json.dumps(
        {"exostudy_version": version(), **report.as_json()}, indent=1))
    report.files.append("summary.json")
    return report
