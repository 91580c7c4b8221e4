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
  sessions keep each study's results endpoint to one rate setting. The model set and
  utility set belong to the first study and are used by both.
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
  at real time until the inlet has caught up (`_drain_emg`), so nothing overflows.
"""

from __future__ import annotations

import json
import math
import os
import secrets
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from backend.analysis import tick_queries
from backend.analysis.results import FIGURE_NAMES
from backend.analysis.virtual_study_speeds import COLLECTION_SPEED, DEFAULT_SPEED
from backend.core.resources import version
from backend.live.local_server import ApiClient, Response, serving
from controller.controllers import registry
from controller.device.base import MAX_SPEED, SAMPLE_PERIOD_S

RATE_SETTINGS: dict[str, float | None] = {"paper-rates": None, "100hz": 100.0}
#: liblsl's configuration for the virtual study (written into its folder): streams are
#: found on this machine only, by multicast on the machine scope and unicast to the
#: loopback address, so the simulated amplifier and the server need no network.
LSL_CONFIG = ("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
              "[lab]\nKnownPeers = {127.0.0.1}\n")
#: A wait on the worker fails only after this many seconds without progress (ticks,
#: job progress): a loaded machine makes the study slower, never wrong.
STALL_S = 120.0
#: What the virtual studies' exports say about themselves (BIDS' dataset description):
#: simulated data made by this software, free of any right (CC0).
DATASET_INFO: dict[str, Any] = {
    "authors": ["ExoStudy virtual study", "ExoStudy contributors"],
    "license": "CC0-1.0",
    "institution_name": "none (simulated participants)",
    "institution_address": "none (simulated participants)",
    "institution_department": "none (simulated participants)",
    "instructions": "none: virtual participants follow the simulator's script",
}
#: Tables written per rate setting (questionnaires are left out, see the docstring).
WRITTEN_TABLES = ("performance", "performance_by_kind", "false_positives", "onset_to_lock",
                  "lifts")
#: See `VirtualStudyConfig.emg_idle_speed`.
EMG_IDLE_SPEED = 1.0
#: The simulated amplifier's stream (`SimulatedDevice` with `emg_lsl`) and its spare inputs.
EMG_STREAM = "ExoStudy-SimEMG"
EMG_SPARE = ("spare_1", "spare_2", "spare_3", "spare_4")
#: The EMG study's settings: the project's chain with a 50 Hz notch (the simulated
#: amplifier hums at 50 Hz), normalised to the task peak (no MVC in a simulation).
EMG_SETTINGS: dict[str, Any] = {"processing": {"notch_hz": 50}, "normalisation": "task_peak",
                                "mains_hz": 50}
QUESTIONNAIRE_NOTE = ("Questionnaires (SUS, EUS, preference) are not part of a virtual "
                      "study: virtual participants give no answers, and none are invented.")


@dataclass(frozen=True)
class VirtualStudyConfig:
    """What to run. Seeds: evaluation participant j (0-based) is `seed*100 + 1 + j`,
    data-collection participant i is `seed*100 + 50 + i`."""

    out: Path
    participants: int = 8
    data_participants: int = 6
    eumc: int = 3
    seed: int = 1
    speed: float = DEFAULT_SPEED
    collection_speed: float = COLLECTION_SPEED
    eval_script: str = "paper-evaluation"
    data_scripts: tuple[str, ...] = ("squat-sequence", "stoop-sequence")
    rates: tuple[str, ...] = tuple(RATE_SETTINGS)
    margin_s: float = 6.0
    model_evaluation: bool = True
    #: EMG on LSL and the baseline conditions in the first rate setting's study (off:
    #: the paper's protocol alone, which is several times faster).
    emg: bool = False
    baseline_script: str = "lift-evaluation"
    #: Simulator speed-up in the pause after a trial that records EMG, while the
    #: server's inlet catches up with what the sped-up trial produced (LSL buffers it).
    emg_idle_speed: float = EMG_IDLE_SPEED

    def __post_init__(self) -> None:
        if self.participants < 1:
            raise ValueError("participants: need at least 1")
        if self.data_participants < 2:
            raise ValueError("data_participants: need at least 2 to fit and cross-validate")
        if not 0 <= self.eumc <= self.participants:
            raise ValueError(f"eumc: must be within 0..{self.participants}")
        if not 1.0 <= self.speed <= MAX_SPEED:
            raise ValueError(f"speed: must be within 1..{MAX_SPEED:g} times real time")
        if not 1.0 <= self.collection_speed <= MAX_SPEED:
            raise ValueError(
                f"collection_speed: must be within 1..{MAX_SPEED:g} times real time")
        unknown = [r for r in self.rates if r not in RATE_SETTINGS]
        if unknown or not self.rates:
            raise ValueError(f"rates: choose from {', '.join(RATE_SETTINGS)}")
        if not 0 <= self.seed <= 20_000_000:
            raise ValueError("seed: must be within 0..20000000")

    def eval_seed(self, j: int) -> int:
        """Seed of evaluation participant j."""
        return self.seed * 100 + 1 + j

    def data_seed(self, i: int) -> int:
        """Seed of data-collection participant i."""
        return self.seed * 100 + 50 + i


@dataclass
class TrialTiming:
    """How one trial ran: wall time, ticks, the rate reached, device-time gaps."""

    trial_id: int
    study: str
    participant: str
    controller: str
    wall_s: float
    ticks: int
    ticks_per_s: float
    gaps: int
    calibration_attempts: int = 0


@dataclass
class VirtualStudyReport:
    """What a run did and where it wrote it."""

    out: Path
    wall_s: float = 0.0
    phases: dict[str, float] = field(default_factory=dict)
    studies: dict[str, int] = field(default_factory=dict)
    model_set_id: int = 0
    utility_set_id: int = 0
    trials: list[TrialTiming] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def as_json(self) -> dict[str, Any]:
        """JSON-able form (written as `summary.json`)."""
        d = asdict(self)
        d["out"] = str(self.out)
        return d


class VirtualStudyError(RuntimeError):
    """The server refused a step; the message names it."""


def _ok(r: Response, code: int = 200) -> Any:
    if r.status_code != code:
        raise VirtualStudyError(f"{r.method} {r.path}: {r.status_code} {r.text[:500]}")
    return r.json()


class _Driver:
    """The experimenter's side: REST calls, and waiting on the device's ticks."""

    def __init__(self, client: ApiClient, speed: float, log: Callable[[str], None]) -> None:
        self.c = client
        self.speed = speed
        self.log = log

    def ticks(self) -> int:
        return int(_ok(self.c.get("/api/health"))["worker"]["ticks"])

    def _poll_s(self) -> float:
        return min(0.25, max(0.02, 2.0 / self.speed))

    def wait_ticks(self, target: int) -> None:
        """Until the worker has produced `target` ticks since the simulation started;
        fails only if the tick count stops moving for `STALL_S`."""
        last, since = -1, time.monotonic()
        while (n := self.ticks()) < target:
            if n != last:
                last, since = n, time.monotonic()
            elif time.monotonic() - since > STALL_S:
                raise VirtualStudyError(f"the worker stopped at {n} of {target} ticks "
                                        f"(no progress for {STALL_S:.0f} s)")
            time.sleep(self._poll_s())

    def wait_run_over(self, run_id: int, seconds: float) -> None:
        """Until the worker has ended the timed run `run_id` (after `seconds` of device
        time): the trial then holds exactly that, however late this side looks. Fails
        only if the worker's ticks stop moving for `STALL_S`."""
        last, since = -1, time.monotonic()
        while True:
            h = _ok(self.c.get("/api/health"))
            if h["database"]["current_run_id"] != run_id:
                return
            n = int(h["worker"]["ticks"])
            if n != last:
                last, since = n, time.monotonic()
            elif time.monotonic() - since > STALL_S:
                raise VirtualStudyError(f"run {run_id} did not end: no ticks for "
                                        f"{STALL_S:.0f} s ({seconds:.0f} s of device time "
                                        "were asked for)")
            time.sleep(self._poll_s())

    def simulate(self, seed: int, script: str, speed: float) -> None:
        """Another virtual participant or script: the worker swaps its simulator."""
        self.speed = speed
        # Returns once the new wearer's ticks arrive.
        _ok(self.c.post("/api/worker/simulation",
                        json={"seed": seed, "script": script, "speed": speed}))

    def job(self, job_id: int) -> None:
        """Until the job is done; fails if it fails, or makes no progress (status or
        fraction) for `STALL_S`."""
        last: tuple[str, float] | None = None
        since = time.monotonic()
        while True:
            job = _ok(self.c.get(f"/api/jobs/{job_id}"))
            if job["status"] == "done":
                return
            if job["status"] in ("failed", "cancelled"):
                raise VirtualStudyError(f"job {job_id} {job['status']}: {job['message']}")
            state = (str(job["status"]), float(job.get("progress") or 0.0))
            if state != last:
                last, since = state, time.monotonic()
            elif time.monotonic() - since > STALL_S:
                raise VirtualStudyError(f"job {job_id} made no progress for {STALL_S:.0f} s")
            time.sleep(0.1)

    def calibrate(self, tries: int = 60) -> int:
        """Calibrate the E-UMC; the wearer has to stand still for 1 s, so retry while
        they move. Returns the number of attempts."""
        for attempt in range(1, tries + 1):
            r = self.c.post("/api/worker/calibrate", json={"seconds": 1.0})
            if r.status_code == 200:
                return attempt
            if r.status_code != 422:
                _ok(r)
        raise VirtualStudyError(f"calibration failed {tries} times: the wearer never stood "
                                "still for a second")


def _participant_body(seed: int, code: str) -> dict[str, Any]:
    from controller.sim.participant import VirtualParticipant

    vp = VirtualParticipant.from_seed(seed)
    return {"code": code, "age": 20 + seed % 30, "sex": vp.sex,
            "height_m": round(vp.height_m, 3), "mass_kg": round(vp.mass_kg, 1),
            "consent_date": "2026-11-22",
            "notes": f"virtual participant, simulator seed {seed}"}


def _script_s(seed: int, script: str) -> float:
    from controller.sim.exoskeleton import SimulatedExoskeleton

    return float(SimulatedExoskeleton(seed=seed, script=script).duration)


def _collect(d: _Driver, cfg: VirtualStudyConfig, study_id: int) -> list[int]:
    """Record and segment every data-collection participant; the segment ids."""
    segment_ids: list[int] = []
    for i in range(cfg.data_participants):
        seed = cfg.data_seed(i)
        p = _ok(d.c.post(f"/api/studies/{study_id}/participants",
                         json=_participant_body(seed, f"D{i + 1:02d}")), 201)
        sess = _ok(d.c.post(f"/api/participants/{p['id']}/sessions",
                            json={"kind": "data_collection", "precompression_pct": 25}), 201)
        for script in cfg.data_scripts:
            d.simulate(seed, script, cfg.collection_speed)
            rec = _ok(d.c.post(f"/api/sessions/{sess['id']}/recordings",
                               json={"label": script}), 201)
            # Until the end of the first repetition (the worker's tick count is the
            # device's sample number since the simulation started) and 1.5 s into the
            # next one's first stand: no lift is cut at the end. A lift that passed while
            # the recording was being started is simply not in it.
            end_s = _script_s(seed, script) + 1.5
            d.wait_ticks(round(end_s / SAMPLE_PERIOD_S))
            _ok(d.c.post(f"/api/recordings/{rec['id']}/stop"))
            segs = _ok(d.c.post(f"/api/recordings/{rec['id']}/segment"))
            segment_ids += [s["id"] for s in segs
                            if s["label"] in ("squat", "stoop_left", "stoop_right")]
        d.log(f"data collection: D{i + 1:02d} recorded ({len(segment_ids)} segments so far)")
    return segment_ids


def _gaps(engine: Any, run_id: int) -> tuple[int, int]:
    """Stored ticks of a run and how many device-time steps exceed 15 ms."""
    t = tick_queries.columns(engine, run_id, fields=("t",))["t"]
    if t.size < 2:
        return int(t.size), 0
    dt = np.diff(t[np.isfinite(t)])
    return int(t.size), int(np.count_nonzero(dt > 0.015))


def _evaluate(d: _Driver, cfg: VirtualStudyConfig, studies: dict[str, int], ms_id: int,
              us_id: int, report: VirtualStudyReport, engine: Any) -> None:
    """Every evaluation participant: both rate settings' trials, back to back."""
    for j in range(cfg.participants):
        seed = cfg.eval_seed(j)
        code = f"P{j + 1:02d}"
        plans: list[tuple[str, list[dict[str, Any]]]] = []
        sessions: dict[str, int] = {}
        for label, study_id in studies.items():
            p = _ok(d.c.post(f"/api/studies/{study_id}/participants",
                             json=_participant_body(seed, code)), 201)
            sess = _ok(d.c.post(f"/api/participants/{p['id']}/sessions",
                                json={"kind": "evaluation", "precompression_pct": 25}), 201)
            body: dict[str, Any] = {"tasks": [cfg.eval_script], "model_set_id": ms_id,
                                    "utility_set_id": us_id, "include_eumc": j < cfg.eumc}
            if cfg.emg and label == cfg.rates[0]:
                body.update(include_baselines=True, baseline_tasks=[cfg.baseline_script])
                sessions[label] = sess["id"]
            plan = _ok(d.c.post(f"/api/sessions/{sess['id']}/trials/plan", json=body), 201)
            plans.append((label, plan))
        d.simulate(seed, cfg.eval_script, cfg.speed)
        # One calibration per participant, as per donning: the runtime keeps it for
        # every later E-UMC trial of this participant.
        calibrating = any(registry.needs_calibration(t["controller"])
                          for _, plan in plans for t in plan)
        attempts = d.calibrate() if calibrating else 0
        script = cfg.eval_script
        for label, plan in plans:
            rate = RATE_SETTINGS[label]
            sub = _subscribe_emg(d, sessions[label]) if label in sessions else None
            for trial in plan:
                if trial["task"] != script or sub is not None or d.speed != cfg.speed:
                    # A baseline's lifts or back to the protocol; with EMG every trial
                    # from the script's start at full speed, the pause after it slow.
                    script = trial["task"]
                    d.simulate(seed, script, cfg.speed)
                trial_s = _script_s(seed, script) + cfg.margin_s
                t0 = time.monotonic()
                body = {"duration_s": trial_s}
                if rate is not None:
                    body["rate_hz"] = rate
                started = _ok(d.c.post(f"/api/trials/{trial['id']}/start", json=body))
                d.wait_run_over(started["run_id"], trial_s)
                ended = _lsl_now() if sub is not None else 0.0
                stopped = _ok(d.c.post(f"/api/trials/{trial['id']}/stop",
                                       json={"outcome": "completed"}))
                if sub is not None:
                    d.simulate(seed, script, cfg.emg_idle_speed)
                    _drain_emg(d, sessions[label], sub, ended)
                wall = time.monotonic() - t0
                n, gaps = _gaps(engine, stopped["run_id"])
                report.trials.append(TrialTiming(trial["id"], label, code, trial["controller"],
                                                 round(wall, 2), n, round(n / wall, 1), gaps,
                                                 attempts if registry.needs_calibration(
                                                     trial["controller"]) else 0))
            if sub is not None:
                _ok(d.c.request("DELETE",
                                f"/api/sessions/{sessions[label]}/emg-streams/{sub}"))
        d.log(f"evaluation: {code} done ({sum(len(p) for _, p in plans)} trials)")


def _lsl_now() -> float:
    import pylsl

    return float(pylsl.local_clock())


def _drain_emg(d: _Driver, session_id: int, sub: int, until: float) -> None:
    """Until the server's inlet has recorded the EMG up to `until` (LSL clock): a sped-up
    trial produces EMG faster than a loaded server stores it, and LSL buffers the rest
    (6 min of samples); the pause after each trial lets the inlet catch up, so nothing
    overflows. Fails only if the inlet makes no progress for `STALL_S`."""
    last, since = None, time.monotonic()
    while True:
        streams = _ok(d.c.get(f"/api/sessions/{session_id}/emg-streams"))
        t = next((s.get("last_time") for s in streams if s["id"] == sub), None)
        if t is not None and t >= until:
            return
        if t != last:
            last, since = t, time.monotonic()
        elif time.monotonic() - since > STALL_S:
            raise VirtualStudyError(f"the EMG inlet of session {session_id} made no "
                                    f"progress for {STALL_S:.0f} s")
        time.sleep(0.1)


def _subscribe_emg(d: _Driver, session_id: int) -> int:
    """Record the simulated amplifier with the session (as an experimenter subscribes
    the lab's amplifier); the subscription's id. The stream appears once the simulator
    runs; a subscription is refused (409) until it is visible. By source id: this
    process is the server, the worker's parent, so the id names this study's simulator
    alone; by name, the inlet could record another simulator on the machine (another
    virtual study, a test), whose samples then stand in for this one's."""
    from controller.sim.emg_amplifier import server_source_id

    deadline = time.monotonic() + STALL_S
    while True:
        r = d.c.post(f"/api/sessions/{session_id}/emg-streams",
                     json={"name": EMG_STREAM, "source_id": server_source_id(os.getpid()),
                           "ignore_labels": list(EMG_SPARE)})
        if r.status_code == 201:
            sub = int(r.json()["id"])
            break
        if r.status_code != 409 or time.monotonic() > deadline:
            _ok(r, 201)
        time.sleep(0.2)
    # Until the inlet records (its first samples make the recording), so no trial
    # starts before its EMG does.
    while time.monotonic() < deadline:
        streams = _ok(d.c.get(f"/api/sessions/{session_id}/emg-streams"))
        if any(s["id"] == sub and s.get("connected") for s in streams):
            return sub
        time.sleep(0.05)
    raise VirtualStudyError(f"the EMG stream of session {session_id} never connected")


def _setup_emg(d: _Driver, study_id: int) -> None:
    """The EMG study's montage (the simulated amplifier's 12 muscle channels, SENIAM
    where SENIAM has the muscle) and its processing settings."""
    from controller.sim.emg_amplifier import (
        ELECTRODE,
        INTER_ELECTRODE_MM,
        PLACEMENT,
        REFERENCE,
    )
    from controller.sim.muscles import CHANNELS, channel_label

    channels = [{"label": channel_label(m, side), "muscle": m, "side": side,
                 "placement": PLACEMENT[m], "electrode_type": ELECTRODE,
                 "inter_electrode_distance_mm": INTER_ELECTRODE_MM, "reference": REFERENCE}
                for m, side in CHANNELS]
    _ok(d.c.request("PUT", f"/api/studies/{study_id}/emg-montage", json_body={
        "placement_scheme": "SENIAM where available", "channels": channels}))
    _ok(d.c.request("PUT", f"/api/studies/{study_id}/emg-settings", json_body=EMG_SETTINGS))


def _write(path: Path, data: bytes | str, report: VirtualStudyReport) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        path.write_text(data)
    else:
        path.write_bytes(data)
    report.files.append(str(path.relative_to(report.out)))


def _outputs(d: _Driver, cfg: VirtualStudyConfig, studies: dict[str, int], ms_id: int,
             us_id: int, report: VirtualStudyReport) -> None:
    out = cfg.out
    _write(out / "models.json",
           json.dumps(_ok(d.c.get(f"/api/model-sets/{ms_id}/document")), indent=1), report)
    _write(out / "utilities.json",
           json.dumps(_ok(d.c.get(f"/api/utility-sets/{us_id}/document")), indent=1), report)
    for label, sid in studies.items():
        folder = out / label
        doc = _ok(d.c.get(f"/api/studies/{sid}/results"))
        _write(folder / "results.json", json.dumps(doc, indent=1), report)
        for table in WRITTEN_TABLES:
            for fmt in ("csv", "md"):
                r = d.c.get(f"/api/studies/{sid}/results/{table}.{fmt}")
                _write(folder / f"{table}.{fmt}", _ok_text(r), report)
        for fig in FIGURE_NAMES:
            for fmt in ("png", "svg"):
                r = d.c.get(f"/api/studies/{sid}/figures/{fig}.{fmt}")
                _write(folder / f"{fig}.{fmt}", _ok_bytes(r), report)
        if cfg.emg and label == cfg.rates[0]:
            _muscle_outputs(d, sid, folder, report)
        first = next((t for t in report.trials
                      if t.study == label and registry.estimates_intent(t.controller)), None)
        if first is not None:
            for fmt in ("png", "svg"):
                r = d.c.get(f"/api/trials/{first.trial_id}/figures/timeline.{fmt}")
                _write(folder / f"timeline-trial-{first.trial_id}.{fmt}", _ok_bytes(r), report)
    if cfg.model_evaluation:
        sid = next(iter(studies.values()))
        lopo = _ok(d.c.get(f"/api/studies/{sid}/model-evaluation",
                           params={"model_set_id": ms_id, "utility_set_id": us_id}))
        _write(out / "model_evaluation.json", json.dumps(lopo, indent=1), report)
        _write(out / "model_evaluation.md", lopo_markdown(lopo), report)


def _muscle_outputs(d: _Driver, sid: int, folder: Path, report: VirtualStudyReport) -> None:
    """The muscle-activity results of the EMG study: JSON, every table as CSV, the
    reductions as Markdown, both figures."""
    doc = _ok(d.c.get(f"/api/studies/{sid}/muscle-results"))
    _write(folder / "muscle_results.json", json.dumps(doc, indent=1), report)
    for table in ("lifts", "summary", "reductions", "repeated_measures"):
        r = d.c.get(f"/api/studies/{sid}/muscle-results/{table}.csv")
        _write(folder / f"muscle_{table}.csv", _ok_text(r), report)
    r = d.c.get(f"/api/studies/{sid}/muscle-results/reductions.md")
    _write(folder / "muscle_reductions.md", _ok_text(r), report)
    for fig in ("muscle_envelopes", "muscle_reduction"):
        for fmt in ("png", "svg"):
            r = d.c.get(f"/api/studies/{sid}/muscle-figures/{fig}.{fmt}")
            _write(folder / f"{fig}.{fmt}", _ok_bytes(r), report)


def _ok_text(r: Response) -> str:
    if r.status_code != 200:
        raise VirtualStudyError(f"GET {r.path}: {r.status_code} {r.text[:300]}")
    return r.text


def _ok_bytes(r: Response) -> bytes:
    if r.status_code != 200:
        raise VirtualStudyError(f"GET {r.path}: {r.status_code} {r.text[:300]}")
    return r.content


def lopo_markdown(lopo: dict[str, Any]) -> str:
    """The leave-one-participant-out result as Markdown tables."""
    def pct(x: float | None) -> str:
        return "" if x is None else f"{100 * x:.1f} %"

    lines = ["**Leave-one-participant-out evaluation of the motion models (UMC replay)**", "",
             "| held out | segments | recognised | correct decisions |",
             "| --- | --- | --- | --- |"]
    for f in lopo["folds"]:
        if "error" in f:
            lines.append(f"| {f['participant']} | {f['error']} | | |")
        else:
            lines.append(f"| {f['participant']} | {f['segments']} | {f['recognised']} | "
                         f"{f['correct']} |")
    lines += ["", f"Recognition accuracy {pct(lopo['recognition_accuracy'])}, decision "
              f"accuracy {pct(lopo['decision_accuracy'])} over {lopo['segments']} segments.",
              ""]
    for title, key in (("Recognition (first posterior >= 0.5 in the first half)",
                        "recognition_confusion"),
                       ("First lock decision in the first half", "decision_confusion")):
        conf: dict[str, dict[str, int]] = lopo[key]
        cols = list(next(iter(conf.values())))
        lines += [f"**{title}**", "", "| true \\ predicted | " + " | ".join(cols) + " |",
                  "|" + " --- |" * (len(cols) + 1)]
        lines += [f"| {k} | " + " | ".join(str(v[c]) for c in cols) + " |"
                  for k, v in conf.items()]
        lines.append("")
    return "\n".join(lines)


def _readme(cfg: VirtualStudyConfig, report: VirtualStudyReport) -> str:
    tps = [t.ticks_per_s for t in report.trials]
    lines = [
        "# Virtual study", "",
        f"{cfg.participants} evaluation participants ({cfg.eumc} with E-UMC), "
        f"{cfg.data_participants} data-collection participants, seed {cfg.seed}, "
        f"simulator speed {cfg.speed:g}x, script `{cfg.eval_script}` per trial.", "",
        f"Wall time {report.wall_s:.0f} s (" + ", ".join(
            f"{k} {v:.0f} s" for k, v in report.phases.items()) + ").",
        f"Ticks per second during trials: median {np.median(tps) if tps else math.nan:.0f} "
        f"(requested {cfg.speed * 100:.0f}); device-time gaps: "
        f"{sum(t.gaps for t in report.trials)}.", "",
        "Everything is stored in `study.db` (studies " + ", ".join(
            f"{k}: {v}" for k, v in report.studies.items()) + "); one folder per rate "
        "setting holds the tables (CSV long form, Markdown in the paper's layout) and the "
        "figures (PNG, SVG). `models.json` and `utilities.json` are the sets the trials "
        "used, in the format `exostudy replay` reads.", "", QUESTIONNAIRE_NOTE, "",
    ]
    for label in cfg.rates:
        lines += [f"## {label}", ""]
        for table in ("performance", "false_positives", "onset_to_lock"):
            p = cfg.out / label / f"{table}.md"
            if p.is_file():
                lines += [p.read_text(), ""]
        p = cfg.out / label / "muscle_reductions.md"
        if p.is_file():
            lines += ["### Muscle activity", "",
                      "EMG of the simulated wearer's muscles, published on LSL by the "
                      "simulated amplifier and recorded through the server; the "
                      "reduction of each muscle's mean envelope over the lifts against "
                      "each baseline condition (figures `muscle_reduction.png`, "
                      "`muscle_envelopes.png`; every lift in `muscle_lifts.csv`). The "
                      "simulation does not model the device's mass or straps, so the two "
                      "baselines differ only by chance. The stream is sped up with the "
                      "simulation, so its recordings carry `rate_mismatch`.", "",
                      p.read_text(), ""]
    if (cfg.out / "model_evaluation.md").is_file():
        lines += ["## Motion models, leave one participant out", "",
                  (cfg.out / "model_evaluation.md").read_text()]
    return "\n".join(lines) + "\n"


def run(cfg: VirtualStudyConfig, log: Callable[[str], None] = print) -> VirtualStudyReport:
    """Run the virtual study into `cfg.out` (which must not hold a `study.db` yet)."""
    from backend.core.config import Settings
    from backend.db import migrate
    from backend.db.engine import make_engine, make_session_factory
    from backend.main import create_app
    from backend.study import accounts

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
            client.token = _ok(client.post("/api/auth/token", json={
                "username": "virtual-study", "password": password}))["access_token"]
            d = _Driver(client, cfg.speed, log)
            studies: dict[str, int] = {}
            for label in cfg.rates:
                name = (f"Virtual study seed {cfg.seed} ({label}) "
                        f"{time.strftime('%Y-%m-%d %H:%M:%S')}")
                desc = ("Virtual participants through the live server; every controller at "
                        "100 Hz" if RATE_SETTINGS[label] else
                        "Virtual participants through the live server; the paper's rates")
                studies[label] = _ok(client.post("/api/studies", json={
                    "name": name, "description": desc, "dataset_info": DATASET_INFO}),
                    201)["id"]
            report.studies = studies
            if cfg.emg:
                _setup_emg(d, studies[cfg.rates[0]])
            first = next(iter(studies.values()))
            t0 = time.monotonic()
            segment_ids = _collect(d, cfg, first)
            report.phases["data collection"] = time.monotonic() - t0
            t0 = time.monotonic()
            ms = _ok(client.post(f"/api/studies/{first}/model-sets", json={
                "name": "virtual data collection", "segment_ids": segment_ids}), 202)
            us = _ok(client.post(f"/api/studies/{first}/utility-sets", json={
                "name": "simulated reference, 25 %", "precompression_pct": 25}), 202)
            d.job(ms["job_id"])
            d.job(us["job_id"])
            report.model_set_id, report.utility_set_id = ms["id"], us["id"]
            report.phases["models and utilities"] = time.monotonic() - t0
            log(f"models {ms['id']} and utilities {us['id']} ready")
            t0 = time.monotonic()
            _evaluate(d, cfg, studies, ms["id"], us["id"], report, app.state.engine)
            report.phases["evaluation"] = time.monotonic() - t0
            t0 = time.monotonic()
            # No trial runs any more: the simulated wearer back to real time, or the
            # worker would go on producing (and the server storing) 100x ticks nobody
            # reads while the outputs are computed (a third of their time, profiled).
            d.simulate(cfg.eval_seed(0), cfg.eval_script, 1.0)
            _outputs(d, cfg, studies, ms["id"], us["id"], report)
            report.phases["tables and figures"] = time.monotonic() - t0
    finally:
        engine.dispose()
    report.wall_s = time.monotonic() - t_start
    report.phases = {k: round(v, 1) for k, v in report.phases.items()}
    report.wall_s = round(report.wall_s, 1)
    (cfg.out / "README.md").write_text(_readme(cfg, report))
    report.files.append("README.md")
    (cfg.out / "summary.json").write_text(json.dumps(
        {"exostudy_version": version(), **report.as_json()}, indent=1))
    report.files.append("summary.json")
    return report

