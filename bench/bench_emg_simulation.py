"""CPU the simulated wearer's EMG costs: `EmgTap.emit` per 100 Hz tick, 16 channels at 2 kHz.

Why: in a virtual study with `--emg` the worker process produces the wearer's EMG tick by
tick (muscle activation, 20 samples of sEMG, an LSL chunk); that was most of the
worker's CPU. The wearer's moments and samples are recorded first from a real
`SimulatedExoskeleton` (not timed), then replayed, so only the EMG's own cost is
measured: CPU seconds (`time.process_time`, every thread of this process, liblsl's
included) per simulated minute, best of three, for the current code and for the per-tick
code it replaced (`tests/controller/sim/reference_emg.py`, the tests' oracle, which
produces the same samples):

- `generate`: activation and sEMG for one tick (`EmgTap.emit` without LSL);
- `activation`: one tick's muscle activation alone;
- `push`: one tick's `SurfaceEmgGenerator.push` alone;
- `publish` (current only): `emit` with an LSL outlet and per-sample ("spread") stamps,
  as the worker's in-process simulator runs it.

    .venv/bin/python bench/bench_emg_simulation.py [--seconds 120] [--seed 3] [--record]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import uuid
from collections.abc import Callable
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
from tests.controller.sim.reference_emg import (  # noqa: E402
    ReferenceGenerator,
    ReferenceMuscles,
    ReferenceTap,
)

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


def cpu_emit_reference(replay: Replay) -> float:
    """CPU seconds of the replaced per-tick code for every recorded tick."""
    replay.k = -1
    tap = ReferenceTap(MuscleModel.for_participant(replay.participant), replay.seed)
    start = time.process_time()
    while not replay.finished:
        sample = replay.tick(None)
        tap.emit(sample, replay.human_torques(), replay.true_torques())
    return time.process_time() - start


def cpu_activation(replay: Replay, reference: bool) -> float:
    """CPU seconds of one tick's activation, tick by tick."""
    model = MuscleModel.for_participant(replay.participant)
    pairs = list(zip(replay.human, replay.exo, strict=True))
    start = time.process_time()
    if reference:
        old = ReferenceMuscles(model)
        for h, e in pairs:
            old.activation(h, e)
    else:
        for h, e in pairs:
            model.tick_activation(h, e)
    return time.process_time() - start


def cpu_push(replay: Replay, reference: bool) -> float:
    """CPU seconds of the generator's `push`, one tick a call."""
    model = MuscleModel.for_participant(replay.participant)
    act = np.zeros((len(replay.human), N_CHANNELS))
    act[:, :12] = model.activation(np.array(replay.human), np.array(replay.exo))
    gen = (ReferenceGenerator if reference else SurfaceEmgGenerator)(
        N_CHANNELS, replay.seed, None, 20)
    start = time.process_time()
    for row in act:
        gen.push(row)
    return time.process_time() - start


def best_of_three(run: Callable[[], float]) -> float:
    """The least CPU of three runs after a warm one (imports, liblsl, caches)."""
    run()
    return min(run() for _ in range(3))


def main() -> None:
    """Print CPU seconds per simulated minute, best of three runs each."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120.0, help="simulated seconds")
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--record", action="store_true", help="write bench/results/")
    args = parser.parse_args()
    load = load_average()
    ticks = round(args.seconds * 100)
    replay = Replay(args.seed, ticks)
    minutes = ticks * replay.dt / 60.0
    cases: dict[str, tuple[Callable[[], float], Callable[[], float] | None]] = {
        "generate": (lambda: cpu_emit(replay, publish=False),
                     lambda: cpu_emit_reference(replay)),
        "activation": (lambda: cpu_activation(replay, False),
                       lambda: cpu_activation(replay, True)),
        "push": (lambda: cpu_push(replay, False), lambda: cpu_push(replay, True)),
        "publish": (lambda: cpu_emit(replay, publish=True), None),
    }
    rows: list[list[object]] = []
    for name, (new, old) in cases.items():
        now = best_of_three(new) / minutes
        before = best_of_three(old) / minutes if old is not None else None
        rows.append([name, round(now, 3), "-" if before is None else round(before, 3),
                     "-" if before is None else round(before / now, 1)])
        was = "" if before is None else f"; replaced code {before:6.3f} ({before / now:.1f}x)"
        print(f"{name:>10}: {now:6.3f} CPU s per simulated minute "
              f"({now * replay.dt / 60.0 * 1e6:5.1f} us per tick){was}")
    if args.record:
        path = record("emg_simulation", "python bench/bench_emg_simulation.py --record",
                      ["case", "CPU s / simulated min", "replaced code", "speed-up"],
                      rows, load,
                      note=f"{args.seconds:g} s of {SCRIPT}, seed {args.seed}; best of 3")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
