"""Run every benchmark in turn and print what each reports (`make bench`).

Timing figures depend on the machine and on what else runs: each benchmark measures a
baseline in the same run where one exists, and the guide (docs/benchmarks.md and the
pages it names) records the figures with the conditions they were measured under.
Nothing here is a test: it never fails the build.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCHES = [
    ("onset DTW and UMC tick", ["bench_onset.py"]),
    ("Kalman step and expected-utility decision per call", ["bench_step_costs.py"]),
    ("replay of a 10-minute recording", ["bench_replay.py"]),
    ("simulation speed", ["bench_simulation.py"]),
    ("CSV export of a 10-minute trial", ["bench_export.py"]),
    ("result figures: controller output and muscle envelopes", ["bench_figures.py"]),
    ("tick recorder into SQLite", ["bench_recorder.py"]),
    ("a tick from the worker to a database row: records vs one block",
     ["bench_tick_transport.py"]),
    ("UDP device round trip and emulator lateness", ["bench_udp.py", "--minutes", "1"]),
    ("C device vs Python device: round trip, late samples, watchdog release",
     ["bench_c_device.py", "--minutes", "1"]),
    ("cost of the device link's authentication", ["bench_link_auth.py"]),
    ("device calls of a tick: UDP send and read timeout, simulated reads",
     ["bench_device_calls.py"]),
    ("live path with 0, 3 and 4 browser consoles", ["bench_live.py", "--seconds", "30"]),
    ("live path, all five plots in view", ["bench_live.py", "--seconds", "30",
                                           "--viewport", "1280x2100"]),
    ("console first page, cold", ["bench_console_load.py", "--runs", "10"]),
    ("safety: worker, device and server SIGKILL, watchdog", ["bench_faults.py", "--kills", "6",
                                                      "--repeats", "10"]),
    ("LSL outlets on and off, marker latency", ["bench_lab.py", "--seconds", "30"]),
    ("virtual cohort: 10, 50, 100 participants x 3 controllers", ["bench_cohort.py"]),
    ("100 Hz loop with and without a CPU hog", ["bench_loop_load.py", "--seconds", "20"]),
    ("EMG chain: one hour of 16 channels at 2 kHz", ["bench_emg_processing.py"]),
]


def main() -> int:
    for title, args in BENCHES:
        print(f"\n=== {title} ({' '.join(args)})", flush=True)
        t0 = time.monotonic()
        proc = subprocess.run([sys.executable, str(HERE / args[0]), *args[1:]],
                              cwd=HERE.parent, check=False)
        print(f"--- exit {proc.returncode}, {time.monotonic() - t0:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
