"""Benchmark of the offline EMG chain (`controller.emg.processing.process`).

Run: `.venv/bin/python bench/bench_emg_processing.py [--minutes 60] [--channels 16]`
(about a minute for the full hour).

One hour of 16-channel EMG at 2 kHz (synthetic: amplitude-modulated Gaussian noise with
electrode offsets, float64, 0.92 GB) through DC removal, the 20-450 Hz band-pass, a 50 Hz
notch, rectification and the 6 Hz envelope, in each precision, and with the channels
split over two threads. Target: under 10 s. Peak memory is what `tracemalloc` saw allocated
during the call beyond the input (numpy reports its arrays to it); the output, a float64
array as large as the input, is part of it. Baselines in the same run: one `np.abs` over
the whole array (a pass that only reads and writes every sample once), and the previous
implementation (scipy's `sosfiltfilt` channel by channel, float32 filters), whose
results the kernel reproduces. The numba kernel is compiled (or loaded from its cache)
on a short record before timing.
"""

from __future__ import annotations

import argparse
import sys
import time
import tracemalloc
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from scipy import signal

from bench.record import load_average, record
from controller.emg import processing
from controller.emg.processing import EmgProcessing, design, process
from controller.emg.zero_phase import zero_phase

FS = 2000.0


def _synthetic(minutes: float, channels: int) -> np.ndarray:
    n = int(minutes * 60 * FS)
    rng = np.random.default_rng(0)
    raw = rng.standard_normal((n, channels))
    t = np.arange(n) / FS
    raw *= (1e-4 * (0.3 + np.sin(np.pi * t / 4.0) ** 2))[:, None]
    raw += rng.uniform(-5e-3, 5e-3, channels)
    return raw


def _measure(fn: Callable[[], object]) -> tuple[float, float]:
    tracemalloc.start()
    tracemalloc.reset_peak()
    t0 = time.perf_counter()
    out = fn()
    seconds = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    del out
    return seconds, peak


def _scipy_per_channel(raw: np.ndarray, settings: EmgProcessing) -> np.ndarray:
    """The chain as it was before the kernel: `sosfiltfilt` per channel."""
    d = design(settings, FS)
    dtype = np.float32 if settings.precision == "float32" else np.float64
    out = np.empty(raw.shape)
    for c in range(raw.shape[1]):
        x = raw[:, c]
        y = signal.sosfiltfilt(d.bandpass.astype(dtype), (x - x.mean()).astype(dtype))
        np.abs(y, out=y)
        out[:, c] = signal.sosfiltfilt(d.envelope.astype(dtype), y)
    return out


def _two_threads_of_eight(raw: np.ndarray, settings: EmgProcessing) -> np.ndarray:
    """`process` with the 16 channels split into two blocks of 8 on two threads (the
    alternative to one block of 16 on one thread)."""
    d = design(settings, FS)
    dtype = np.float32 if settings.precision == "float32" else np.float64
    out = np.empty(raw.shape)
    zero_phase(d.bandpass.astype(dtype), raw, out, offset=raw.mean(axis=0), threads=2, lanes=8)
    zero_phase(d.envelope.astype(dtype), out, out, rectify=True, threads=2, lanes=8)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--channels", type=int, default=16)
    args = parser.parse_args()
    load_before = load_average()
    raw = _synthetic(args.minutes, args.channels)
    size_mb = raw.nbytes / 2**20
    print(f"input: {raw.shape[0]} samples x {raw.shape[1]} channels, {size_mb:.0f} MiB float64, "
          f"load {load_before}", flush=True)
    for precision in ("float32", "float64"):  # compile or load the kernel first
        process(raw[:4000], FS, EmgProcessing(notch_hz=50, precision=precision))
    rows: list[list[object]] = []
    base_s, base_mb = _measure(lambda: np.abs(raw))
    rows.append(["np.abs over the whole array (baseline)", f"{base_s:.2f}", f"{base_mb:.0f}"])
    default = EmgProcessing(notch_hz=50)
    exact = EmgProcessing(notch_hz=50, precision="float64")
    threads = processing._threads(raw)
    n_threads = f"{threads} thread" + ("s" if threads > 1 else "")
    calls: list[tuple[str, Callable[[], object]]] = [
        ("previous chain: scipy sosfiltfilt per channel, float32 (baseline)",
         partial(_scipy_per_channel, raw, default)),
        (f"process, float32 filters (default), {n_threads}",
         partial(process, raw, FS, default)),
        (f"process, float64 filters, {n_threads}", partial(process, raw, FS, exact)),
        ("float32 filters, two threads of 8 channels each",
         partial(_two_threads_of_eight, raw, default)),
    ]
    for label, call in calls:
        seconds, peak = _measure(call)
        rows.append([label, f"{seconds:.2f}", f"{peak:.0f}"])
        print(f"{label}: {seconds:.2f} s, peak {peak:.0f} MiB, load {load_average()}",
              flush=True)
    record("emg_processing",
           " ".join(["bench/bench_emg_processing.py", *sys.argv[1:]]),
           ["call", "seconds", "peak memory beyond the input (MiB)"], rows, load_before,
           note=f"{args.minutes:g} min x {args.channels} channels at 2 kHz "
           f"({size_mb:.0f} MiB float64 input; the float64 output is included in the peak). "
           "Target: under 10 s.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
