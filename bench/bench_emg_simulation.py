"""CPU the simulated wearer's EMG costs: `EmgTap.emit` per 100 Hz tick, 16 channels at 2 kHz.

Why: in a virtual study with `--emg` the worker process produces the wearer's EMG tick by
tick (muscle activation, 20 samples of sEMG, an LSL chunk); that was most of the
worker's CPU. The wearer's moments and samples are recorded first from a real
`SimulatedExoskeleton` (not timed), then replayed into an `EmgTap`, so only the EMG's
own cost is measured: CPU seconds (`time.process_time`, every thread of this process,
liblsl's included) per simulated minute, for

- `generate`: activation and sEMG only (`publish=False`);
- `publish`: the same plus an LSL outlet with per-sample ("spread") stamps, as the
  in-process simulator of the worker runs it;
- `activation` and `push`: `MuscleModel.activation` and `SurfaceEmgGenerator.push`
  alone, one tick per call.

    .venv/bin/python bench/bench_emg_simulation.py [--seconds 120] [--seed 3] [--record]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
# liblsl on this machine only (the tests' configuration).
os.environ.setdefault("LSLAPICFG", str(ROOT / "tests" / "backend" / "lab" / "lsl_api.cfg"))

import numpy as np  # noqa: E402

from bench.record import load_average, record  # noqa: E402
from controller.device.base import Sample  # noqa: E402
from controller.sim.emg_amplifier import N_CHANNELS, EmgTap  # noqa: E402
from controller.sim.exoskeleton import SimulatedExoskeleton  # noqa: E402
from controller.sim.muscles import MuscleModel  # noqa: E402
from controller.sim.participant import VirtualParticipant  # noqa: E402
from controller.sim.surface_emg import SurfaceEmgGenerator  # noqa: E402

SCRIPT = "paper-evaluation"


class Replay:
    """A recorded wearer: the samples and moments of a `SimulatedExoskeleton`, again."""

    def __init__(self, seed: int, ticks: int) -> None:
        exo = SimulatedExoskeleton(seed=seed, script=SCRIPT)
        self.dt = exo.dt
        self.seed = exo.seed
        self.participant: VirtualParticipant = exo.participant
        self.samples: list[Sample] = []
        self.human: list[tuple[float, float]] = []
        self.exo: list[tuple[float, float]] = []
        for _ in range(ticks):
            self.samples.append(exo.tick(None))
            self.human.append(exo.human_torques())
            self.exo.append(exo.true_torques())
        self.k = -1

    @property
    def finished(self) -> bool:
        """Every recorded tick has been replayed."""
        return self.k + 1 >= len(self.samples)

    def tick(self, command: object) -> Sample:
        """The next recorded sample."""
        self.k += 1
        return self.samples[self.k]

    def human_torques(self) -> tuple[float, float]:
        """The wearer's moments at the last replayed tick."""
        return self.human[self.k]

    def true_torques(self) -> tuple[float, float]:
        """The exoskeleton's torques at the last replayed tick."""
        return self.exo[self.k]


def cpu_emit(replay: Replay, publish: bool) -> float:
    """CPU seconds to emit every recorded tick through a fresh tap."""
    replay.k = -1
    tap = EmgTap(replay, name=f"bench-simemg-{uuid.uuid4().hex[:8]}", publish=publish,
                 stamping="spread")
    tap.start()
    try:
        start = time.process_time()
        while not replay.finished:
            tap.emit(replay.tick(None))
        return time.process_time() - start
    finally:
        tap.close()


def cpu_activation(replay: Replay) -> float:
    """CPU seconds of `MuscleModel.activation`, one tick a call."""
    model = MuscleModel.for_participant(replay.participant)
    start = time.process_time()
    for h, e in zip(replay.human, replay.exo, strict=True):
        model.activation(h, e)
    return time.process_time() - start


def cpu_push(replay: Replay) -> float:
    """CPU seconds of `SurfaceEmgGenerator.push`, one tick a call."""
    model = MuscleModel.for_participant(replay.participant)
    act = np.zeros((len(replay.human), N_CHANNELS))
    act[:, :12] = model.activation(np.array(replay.human), np.array(replay.exo))
    gen = SurfaceEmgGenerator(N_CHANNELS, replay.seed, upsample=20)
    start = time.process_time()
    for row in act:
        gen.push(row)
    return time.process_time() - start


def main() -> None:
    """Print CPU seconds per simulated minute, best of three runs each."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120.0, help="simulated seconds")
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--record", action="store_true", help="write bench/results/")
    args = parser.parse_args()
    load = load_average()
    ticks = int(round(args.seconds * 100))
    replay = Replay(args.seed, ticks)
    minutes = ticks * replay.dt / 60.0
    cases = {
        "generate": lambda: cpu_emit(replay, publish=False),
        "publish": lambda: cpu_emit(replay, publish=True),
        "activation": lambda: cpu_activation(replay),
        "push": lambda: cpu_push(replay),
    }
    rows: list[list[object]] = []
    for name, run in cases.items():
        run()  # warm: imports, liblsl, caches
        best = min(run() for _ in range(3))
        per_min = best / minutes
        per_tick_us = best / ticks * 1e6
        rows.append([name, round(per_min, 3), round(per_tick_us, 1)])
        print(f"{name:>10}: {per_min:7.3f} CPU s per simulated minute "
              f"({per_tick_us:6.1f} us per tick)")
    if args.record:
        path = record("emg_simulation", "python bench/bench_emg_simulation.py --record",
                      ["case", "CPU s / simulated min", "us / tick"], rows, load,
                      note=f"{args.seconds:g} s of {SCRIPT}, seed {args.seed}; best of 3")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
