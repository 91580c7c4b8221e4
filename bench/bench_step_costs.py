"""Per-call cost of two per-tick building blocks, each beside a baseline in the same run.

The unit tests check what the Kalman velocity filter and the compiled expected-utility
decision compute; their cost depends on the machine and its load, so it is measured
here, as a ratio to a baseline call of the same shape:

- `HipVelocityFilter.step` (both hips, one sample) against a Python method call that
  only stores its two arguments;
- `decide_fast` (4 actions x 4 motions x 101 progress points) against a compiled
  function that takes the same arrays and writes one value.

    .venv/bin/python bench/bench_step_costs.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.record import load_average, record
from controller.decision.expected_utility import decide_fast, warm_up
from controller.intent.kalman import HipVelocityFilter

CALLS = 20_000


class _Store:
    """The baseline for the filter: a method call that keeps its arguments."""

    def __init__(self) -> None:
        self.last = (0.0, 0.0)

    def step(self, left: float, right: float) -> tuple[float, float]:
        self.last = (left, right)
        return self.last


@numba.njit(cache=False)
def _touch(table: NDArray[np.float64], s: NDArray[np.float64],
           post: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """The baseline for the decision: same arguments, one write."""
    out[0] = table[0, 0, 0] + s[0] + post[0]


def _per_call_us(call: Callable[[int], object], repeats: int) -> float:
    """Median over `repeats` rounds of the mean time of one call, in microseconds."""
    rounds = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for k in range(CALLS):
            call(k)
        rounds.append((time.perf_counter() - t0) / CALLS * 1e6)
    return statistics.median(rounds)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    load_before = load_average()

    kalman, store = HipVelocityFilter(), _Store()
    k_us = _per_call_us(lambda k: kalman.step(k * 1e-4, k * 1e-4), args.repeats)
    s_us = _per_call_us(lambda k: store.step(k * 1e-4, k * 1e-4), args.repeats)

    warm_up()
    rng = np.random.default_rng(0)
    table = rng.uniform(-1e4, 0, (4, 4, 101))
    s = np.array([0.1, 0.2, 0.3])
    post = np.array([0.4, 0.3, 0.2, 0.1])
    out = np.empty(4)
    _touch(table, s, post, out)
    d_us = _per_call_us(lambda _k: decide_fast(table, s, post, out), args.repeats)
    t_us = _per_call_us(lambda _k: _touch(table, s, post, out), args.repeats)

    print(f"Kalman step (both hips): {k_us:.2f} us per call; baseline method call "
          f"{s_us:.2f} us; ratio {k_us / s_us:.1f}x")
    print(f"decide_fast (4x4x101):   {d_us:.2f} us per call; baseline compiled call "
          f"{t_us:.2f} us; ratio {d_us / t_us:.1f}x")
    record("step_costs", f"bench/bench_step_costs.py --repeats {args.repeats}",
           ["call", "per call (us)", "baseline", "baseline per call (us)", "ratio"],
           [["Kalman velocity filter step (both hips)", f"{k_us:.2f}",
             "a method call that only stores its two arguments", f"{s_us:.2f}",
             f"{k_us / s_us:.1f}x"],
            ["compiled expected-utility decision (4 x 4 x 101)", f"{d_us:.2f}",
             "a compiled call with the same arguments", f"{t_us:.2f}",
             f"{d_us / t_us:.1f}x"]],
           load_before, note="Median of the repeats; both calls against a tick budget "
           "of 10 ms.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
