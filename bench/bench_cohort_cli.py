"""`exostudy cohort` end to end, as a user runs it: 100 participants x UMC, E-UMC and PEC,
statistics, figures and files, in a fresh process (imports, the default sets from the
data folder, numba's cache). Target: under 15 s.

    .venv/bin/python bench/bench_cohort_cli.py [--participants 100] [--repeats 1]

Baseline in the same run, for the machine's load: a fixed pure-Python loop (10 million
additions; about 0.4 s on a quiet core here) timed just before each cohort. The
`(load)` column is the one-minute load average when the cohort started.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.record import load_average, record  # noqa: E402


def _reference_loop() -> float:
    t0 = time.perf_counter()
    total = 0
    for i in range(10_000_000):
        total += i
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args()
    exe = ROOT / ".venv" / "bin" / "exostudy"
    load_before = load_average()
    rows: list[list[object]] = []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as out:
            ref = _reference_loop()
            load = load_average()
            cmd = [str(exe), "cohort", "--participants", str(args.participants), "--seed", "1",
                   "--out", out]
            t0 = time.perf_counter()
            done = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd=ROOT)
            seconds = time.perf_counter() - t0
        said = done.stdout.strip().splitlines()[-1]
        print(f"{seconds:.1f} s (reference loop {ref:.2f} s, load {load}): {said}", flush=True)
        rows.append([f"exostudy cohort --participants {args.participants} --seed 1",
                     f"{seconds:.1f}", f"{ref:.2f}", load])
    record("cohort_cli", "bench/bench_cohort_cli.py " + " ".join(sys.argv[1:]),
           ["command", "end to end (s)", "reference loop (s)", "(load)"], rows, load_before,
           note="Fresh process each time; the default model and utility sets come from the "
           "data folder (built by the first `exostudy serve` or cohort). Target: under 15 s.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
