"""CPU per tick of the worker's control loop on the simulated exoskeleton, outside EMG.

What a sped-up virtual study pays per tick in the worker process: the simulated
device's sample (mechanism and encoders), the controller's step and its `TickRecord`,
the loop's bookkeeping, and the outbox's packing and pickling of each batch of 100
records (`TickBatch`). Measured as CPU time (`time.process_time`), so other work on the
machine inflates it less than wall time; beside it, in the same run, the simulated
device's reads alone.

    .venv/bin/python bench/bench_worker_tick.py [--ticks 20000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import pickle
import statistics
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from backend import bootstrap
from backend.worker.messages import TickBatch
from bench.record import load_average, record
from controller.controllers.factory import make_controller, needs_models
from controller.runner.loop import ControlLoop
from controller.sim.simulated_device import SimulatedDevice
from controller.tick_record import TickRecord

BATCH = 100
CONTROLLERS = ("none", "umc", "pec")


def _loop_us(name: str, config: Mapping[str, Any], ticks: int) -> float:
    """CPU microseconds per tick of the loop with controller `name`, batches packed."""
    controller = make_controller(name, config)
    controller.warm_up()
    loop = ControlLoop(SimulatedDevice(seed=3, realtime=False, loop=True), controller)
    for _ in range(200):
        loop.tick()
    batch: list[TickRecord] = []
    t0 = time.process_time()
    for _ in range(ticks):
        record_ = loop.tick()
        assert record_ is not None
        batch.append(record_)
        if len(batch) == BATCH:
            pickle.dumps(TickBatch.from_records(1, batch))
            batch = []
    return (time.process_time() - t0) / ticks * 1e6


def _device_us(ticks: int) -> float:
    """CPU microseconds per sample of the simulated device alone."""
    device = SimulatedDevice(seed=3, realtime=False, loop=True)
    for _ in range(200):
        device.read(0.0)
    t0 = time.process_time()
    for _ in range(ticks):
        device.read(0.0)
    return (time.process_time() - t0) / ticks * 1e6


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    load_before = load_average()
    with tempfile.TemporaryDirectory(prefix="exostudy-bench-") as tmp:
        folder = Path(tmp)
        models = bootstrap.ensure_models(folder / "models.json").to_json()
        utilities = bootstrap.ensure_utilities(
            bootstrap.utilities_path(folder, 25.0), 25.0).to_json()
        rows: list[list[object]] = []
        for name in CONTROLLERS:
            config = {"models": models, "utilities": utilities} if needs_models(name) else {}
            us = statistics.median(_loop_us(name, config, args.ticks)
                                   for _ in range(args.repeats))
            rows.append([f"loop tick, controller {name}, batch packed", f"{us:.1f}"])
            print(f"{rows[-1][0]}: {us:.1f} us CPU per tick")
    dev = statistics.median(_device_us(args.ticks) for _ in range(args.repeats))
    rows.append(["baseline: the simulated device's sample alone", f"{dev:.1f}"])
    print(f"{rows[-1][0]}: {dev:.1f} us CPU per tick")
    record("worker_tick", f"bench/bench_worker_tick.py --ticks {args.ticks} "
           f"--repeats {args.repeats}", ["what", "CPU per tick (us)"], rows, load_before,
           note="Median of the repeats; process CPU time, the worker's share of a "
           "sped-up virtual study outside EMG.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
