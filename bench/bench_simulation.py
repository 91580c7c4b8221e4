"""Speed of the simulated wearer and exoskeleton relative to real time.

Run: .venv/bin/python bench/bench_simulation.py [seed]
Prints the speed factor (simulated seconds per wall-clock second) of the full
paper-evaluation protocol for one participant: trajectory generation alone
(`simulate_angles`) and the complete 100 Hz tick loop of `SimulatedExoskeleton`
(plant, encoders, samples). The requirement is at least 200x.
"""

from __future__ import annotations

import sys
import time

from controller.device.base import SAMPLE_PERIOD_S, LockCommand
from controller.sim.exoskeleton import SimulatedExoskeleton
from controller.sim.recording import simulate_angles

SCRIPT = "paper-evaluation"


def bench_angles(seed: int) -> float:
    """Speed factor of generating the true angles."""
    start = time.perf_counter()
    run = simulate_angles(seed, SCRIPT)
    elapsed = time.perf_counter() - start
    return float(run.t.size) * SAMPLE_PERIOD_S / elapsed


def bench_ticks(seed: int) -> tuple[float, float]:
    """Speed factor of ticking the whole protocol (a lock command every 50 ticks) and
    the simulated duration."""
    start = time.perf_counter()
    exo = SimulatedExoskeleton(seed=seed, script=SCRIPT)
    k = 0
    while not exo.finished:
        lock = (k // 50) % 4 == 1
        exo.tick(LockCommand(k, lock, lock) if k % 50 == 0 else None)
        k += 1
    elapsed = time.perf_counter() - start
    return exo.duration / elapsed, exo.duration


def main() -> None:
    """Print both speed factors."""
    seed = int(sys.argv[1]) if len(sys.argv) > 1 else 0
    bench_angles(seed)  # warm caches and imports
    angles = bench_angles(seed)
    ticks, duration = bench_ticks(seed)
    print(f"paper-evaluation, seed {seed}: {duration:.1f} s simulated")
    print(f"trajectory only (simulate_angles): {angles:,.0f}x real time")
    print(f"full tick loop (SimulatedExoskeleton): {ticks:,.0f}x real time")
    print("OK" if min(angles, ticks) >= 200 else "TOO SLOW (< 200x)")


if __name__ == "__main__":
    main()
