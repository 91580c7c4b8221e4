"""A virtual study's evaluation phase: every evaluation participant's planned trials in
every rate setting's study, each a timed run of one script repetition, started and
stopped through the API, with how each trial ran (ticks, rate, device-time gaps) read
back from its stored ticks for the report."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from backend.analysis import tick_queries
from backend.analysis.virtual_study_config import (
    RATE_SETTINGS,
    TrialTiming,
    VirtualStudyConfig,
    VirtualStudyReport,
)
from backend.analysis.virtual_study_driver import (
    Driver,
    ok,
    participant_body,
    script_duration_s,
)
from backend.analysis.virtual_study_emg import drain_emg, lsl_now, subscribe_emg
from controller.controllers import registry


def gaps(engine: Any, run_id: int) -> tuple[int, int]:
    """Stored ticks of a run and how many device-time steps exceed 15 ms."""
    t = tick_queries.columns(engine, run_id, fields=("t",))["t"]
    if t.size < 2:
        return int(t.size), 0
    dt = np.diff(t[np.isfinite(t)])
    return int(t.size), int(np.count_nonzero(dt > 0.015))


def evaluate(d: Driver, cfg: VirtualStudyConfig, studies: dict[str, int],
             sets: dict[int, tuple[int, int]], report: VirtualStudyReport,
             engine: Any) -> None:
    """Every evaluation participant: both rate settings' trials, back to back. `sets`:
    each study's (model set, utility set), which a trial must take from its own study.
    Ends with the simulated wearer at real time.

    How each trial ran (its stored ticks and their gaps) is read once every trial has
    run and the simulation is slow: between two trials the sped-up simulation goes on,
    and what it produces while this side reads (stored, never read) costs more than the
    read."""
    ran: list[tuple[dict[str, Any], str, str, float, int, int]] = []
    for j in range(cfg.participants):
        seed = cfg.eval_seed(j)
        code = f"P{j + 1:02d}"
        plans: list[tuple[str, list[dict[str, Any]]]] = []
        sessions: dict[str, int] = {}
        for label, study_id in studies.items():
            p = ok(d.c.post(f"/api/studies/{study_id}/participants",
                            json=participant_body(seed, code)), 201)
            sess = ok(d.c.post(f"/api/participants/{p['id']}/sessions",
                               json={"kind": "evaluation", "precompression_pct": 25}), 201)
            ms_id, us_id = sets[study_id]
            body: dict[str, Any] = {"tasks": [cfg.eval_script], "model_set_id": ms_id,
                                    "utility_set_id": us_id, "include_eumc": j < cfg.eumc}
            if cfg.emg and label == cfg.rates[0]:
                body.update(include_baselines=True, baseline_tasks=[cfg.baseline_script])
                sessions[label] = sess["id"]
            plan = ok(d.c.post(f"/api/sessions/{sess['id']}/trials/plan", json=body), 201)
            plans.append((label, plan))
        # One calibration per participant, as per donning: the runtime keeps it for
        # every later E-UMC trial of this participant.
        calibrating = any(registry.needs_calibration(t["controller"])
                          for _, plan in plans for t in plan)
        attempts = 0
        if calibrating:
            d.simulate(seed, cfg.eval_script, cfg.speed)
            attempts = d.calibrate()
        for label, plan in plans:
            rate = RATE_SETTINGS[label]
            sub = subscribe_emg(d, sessions[label]) if label in sessions else None
            for trial in plan:
                # Every trial puts its wearer on the simulator as it starts: one
                # repetition of its script from the first sample (the same data however
                # long the requests took), sped up; the worker ends it after `trial_s`
                # of device time and the wearer goes on at real time until the next.
                script = trial["task"]
                trial_s = script_duration_s(seed, script) + cfg.margin_s
                t0 = time.monotonic()
                start: dict[str, Any] = {"duration_s": trial_s, "simulation": {
                    "seed": seed, "script": script, "speed": cfg.speed}}
                if rate is not None:
                    start["rate_hz"] = rate
                started = ok(d.c.post(f"/api/trials/{trial['id']}/start", json=start))
                d.speed = cfg.speed
                d.wait_run_over(started["run_id"], trial_s)
                ended = lsl_now() if sub is not None else 0.0
                stopped = ok(d.c.post(f"/api/trials/{trial['id']}/stop",
                                      json={"outcome": "completed"}))
                if sub is not None:
                    d.simulate(seed, script, cfg.emg_idle_speed)
                    drain_emg(d, sessions[label], sub, ended)
                wall = time.monotonic() - t0
                ran.append((trial, label, code, wall, int(stopped["run_id"]),
                            attempts if registry.needs_calibration(trial["controller"])
                            else 0))
            if sub is not None:
                ok(d.c.request("DELETE",
                               f"/api/sessions/{sessions[label]}/emg-streams/{sub}"))
        d.log(f"evaluation: {code} done ({sum(len(p) for _, p in plans)} trials)")
    # No trial runs any more: the simulated wearer back to real time, or the worker would
    # go on producing (and the server storing) sped-up ticks nobody reads while the
    # outputs are computed (a third of their time, profiled).
    d.simulate(cfg.eval_seed(0), cfg.eval_script, 1.0)
    for trial, label, code, wall, run_id, attempts in ran:
        n, n_gaps = gaps(engine, run_id)
        report.trials.append(TrialTiming(trial["id"], label, code, trial["controller"],
                                         round(wall, 2), n, round(n / wall, 1), n_gaps,
                                         attempts))
