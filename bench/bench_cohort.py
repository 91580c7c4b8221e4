"""Virtual cohort cost: N participants through UMC, E-UMC and PEC with the batch replay
kernel, and what the statistics (bootstrap CIs, Wilcoxon, power curves) add.

Per N: simulation wall time (trajectories, three replays, evaluation of every lift and
gait trial per participant), per-participant cost, and the analysis time. The model set
and utility set are built once beforehand (reported separately: they are not per
cohort when the server's defaults are used). Target: 100 participants x 3 controllers
in under 30 s. Growth with N is reported as per-participant cost at each N.

    .venv/bin/python bench/bench_cohort.py [--sizes 10,50,100] [--processes 1,2] [--no-stats]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.record import load_average, record  # noqa: E402
from controller.evaluation.cohort import (  # noqa: E402
    CohortConfig,
    default_model_set,
    default_utilities,
    simulate_cohort,
)
from controller.evaluation.cohort_report import analyse  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10,50,100")
    ap.add_argument("--no-stats", action="store_true")
    ap.add_argument("--processes", default="1,2", help="process counts to compare")
    args = ap.parse_args()
    t0 = time.perf_counter()
    models = default_model_set()
    t1 = time.perf_counter()
    utilities = default_utilities(25.0)
    t2 = time.perf_counter()
    print(f"model set fitted in {t1 - t0:.1f} s, utilities in {t2 - t1:.1f} s (once)")
    # Warm-up: numba loads its compiled kernels in the first replay.
    simulate_cohort(CohortConfig(participants=2, seed=99), models, utilities)
    print(f"load average before: {os.getloadavg()[0]:.1f}; {os.cpu_count()} cores")
    load_before = load_average()
    rows: list[list[object]] = []
    print("| participants | processes | simulation (s) | per participant (ms) | "
          "statistics (s) | total (s) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for n in (int(s) for s in args.sizes.split(",")):
        for procs in (int(p) for p in args.processes.split(",")):
            a = time.perf_counter()
            cohort = simulate_cohort(CohortConfig(participants=n, seed=1), models, utilities,
                                     processes=procs)
            b = time.perf_counter()
            stats_s = 0.0
            if not args.no_stats:
                analyse(cohort)
                stats_s = time.perf_counter() - b
            print(f"| {n} | {procs} | {b - a:.1f} | {1000 * (b - a) / n:.0f} | "
                  f"{stats_s:.1f} | {b - a + stats_s:.1f} |", flush=True)
            rows.append([n, procs, f"{b - a:.1f}", f"{1000 * (b - a) / n:.0f}",
                         f"{stats_s:.1f}", f"{b - a + stats_s:.1f}"])
    record("cohort", "bench/bench_cohort.py " + " ".join(sys.argv[1:]),
           ["participants", "processes", "simulation (s)", "per participant (ms)",
            "statistics (s)", "total (s)"], rows, load_before,
           note=f"Model set fitted in {t1 - t0:.1f} s and utilities in {t2 - t1:.1f} s, "
           "once, beforehand.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
