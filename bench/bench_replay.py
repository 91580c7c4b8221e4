"""Benchmark of offline replay and of the live tick.

Run: `.venv/bin/python bench/bench_replay.py` (about half a minute once numba's cache
is warm; the first run compiles for a minute or so).

1. A 10-minute recording (60,000 samples at 100 Hz: the simulated squat sequence of
   participant 5, tiled) replayed through the UMC at 100 Hz with `replay_columns`, the
   compiled batch path. Requirement: under 1 s. Also the PEC, the calibrated E-UMC and
   the UMC at the paper's 10 Hz, and the same UMC at 100 Hz through
   `replay_per_tick` (`ControlLoop` + `ReplayDevice`, one Python call per tick, which
   is how replay ran before), with the ratio.
2. `KernelController.step` on the live path (UMC at 100 Hz): p50 and p99 per call,
   timed around `step` on the samples of a `ReplayDevice`, with the garbage collector
   frozen and disabled as the worker loop runs.

Replay timings exclude building the controller (loading the model and utility sets)
and are the best of three runs, the per-tick one a single run (other work shares the
machine's two cores); the load average is printed because that work shows up in them.
"""

from __future__ import annotations

import gc
import os
import pathlib
import sys
import tempfile
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from controller.controllers.factory import load_models, make_controller
from controller.decision.utility_function import compute_utilities
from controller.device.base import SAMPLE_PERIOD_S
from controller.intent.calibration import calibrate
from controller.interface import Controller
from controller.runner.replay import AngleRecording, replay_columns, replay_per_tick
from controller.sim.demonstrations import simulated_model_set
from controller.sim.human_dataset import reference_dataset
from controller.sim.recording import simulate_angles
from controller.sim.replay_device import ReplayDevice

N_SAMPLES = 60_000
REQUIREMENT_S = 1.0


def ten_minutes() -> AngleRecording:
    """60,000 samples: one simulated squat sequence, tiled, with its ground truth."""
    run = simulate_angles(5, "squat-sequence")
    reps = -(-N_SAMPLES // run.t.size)
    q = np.tile(run.q, (reps, 1))[:N_SAMPLES]
    activity = np.tile(run.truth.activity, reps)[:N_SAMPLES].tolist()
    lift = np.tile(run.truth.lift_index, reps)[:N_SAMPLES]
    return AngleRecording(np.arange(N_SAMPLES) * SAMPLE_PERIOD_S, q, activity, lift)


def best_of(n: int, setup: Callable[[], Any], fn: Callable[[Any], Any]) -> float:
    """Shortest of `n` wall-clock runs of `fn(setup())`, seconds; `setup` is not timed
    (a fresh controller per run: loading models and utilities is not replay)."""
    best = float("inf")
    for _ in range(n):
        arg = setup()
        t0 = time.perf_counter()
        fn(arg)
        best = min(best, time.perf_counter() - t0)
    return best


def step_times_us(ctl: Controller, rec: AngleRecording) -> np.ndarray:
    """Wall time of every `step` on the live path, microseconds (commands fed back)."""
    from controller.device.base import LockCommand

    dev = ReplayDevice(rec.t, rec.q)
    dev.open()
    ctl.warm_up()
    out = np.empty(rec.t.size)
    clock = time.perf_counter_ns
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        for k in range(rec.t.size):
            s = dev.read(0.0)
            assert s is not None
            t0 = clock()
            r = ctl.step(s)
            out[k] = clock() - t0
            dev.send(LockCommand(k, r.lock_left, r.lock_right))
    finally:
        gc.enable()
        gc.unfreeze()
    return out / 1e3


def main() -> int:
    """Print the table; exit status 1 if the requirement is missed."""
    folder = pathlib.Path(tempfile.mkdtemp(prefix="bench-replay-"))
    simulated_model_set().save(folder / "models.json")
    compute_utilities(reference_dataset(), 25.0).save(folder / "utilities.json")
    base = {"models_path": str(folder / "models.json"),
            "utilities_path": str(folder / "utilities.json")}
    rec = ten_minutes()
    start = load_models(base).start_posture()
    cal = calibrate(rec.q[:200], start)
    configs: dict[str, tuple[str, dict[str, Any]]] = {
        "UMC @ 100 Hz": ("umc", {"umc_rate_hz": 100}),
        "UMC @ 10 Hz": ("umc", {}),
        "E-UMC (calibrated), 10 Hz triggered": (
            "eumc", {"calibration": [cal.offset_left, cal.offset_right]}),
        "PEC @ 100 Hz": ("pec", {}),
    }

    def build(key: str) -> Controller:
        name, settings = configs[key]
        return make_controller(name, {**base, "settings": settings})

    short = AngleRecording(rec.t[:500], rec.q[:500], None, None)
    for key in configs:  # compile (or load from the numba cache) outside the timings
        replay_columns(short, build(key))
    replay_per_tick(short, build("UMC @ 100 Hz"))

    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; "
          f"{N_SAMPLES} samples = {N_SAMPLES / 6000:.0f} min at 100 Hz; best of 3")
    print(f"{'batch replay (replay_columns)':40s} {'s':>7s} {'us/tick':>8s}")
    times = {}
    for key in configs:
        times[key] = best_of(3, lambda key=key: build(key), lambda c: replay_columns(rec, c))
        print(f"  {key:38s} {times[key]:7.3f} {times[key] / N_SAMPLES * 1e6:8.2f}")
    per_tick = best_of(1, lambda: build("UMC @ 100 Hz"), lambda c: replay_per_tick(rec, c))
    print(f"{'per-tick replay (replay_per_tick)':40s}")
    print(f"  {'UMC @ 100 Hz':38s} {per_tick:7.3f} {per_tick / N_SAMPLES * 1e6:8.2f}")
    print(f"  batch is {per_tick / times['UMC @ 100 Hz']:.1f}x faster than per-tick")

    us = step_times_us(build("UMC @ 100 Hz"), rec)
    print(f"live KernelController.step, UMC @ 100 Hz, {us.size} ticks: "
          f"p50 {np.percentile(us, 50):.1f} us, p99 {np.percentile(us, 99):.1f} us, "
          f"max {us.max():.1f} us")
    ok = times["UMC @ 100 Hz"] < REQUIREMENT_S
    print(f"requirement: 10-minute UMC @ 100 Hz replay < {REQUIREMENT_S:.0f} s: "
          f"{'met' if ok else 'MISSED'} ({times['UMC @ 100 Hz']:.3f} s)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
