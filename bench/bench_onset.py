"""Benchmark of onset detection and of the UMC hot path.

Run: `.venv/bin/python bench/bench_onset.py` (well under a minute).

1. One 30x51 match: `controller.intent.onset.match` (one-shot, validates and inverts the
   covariances every call), `OnsetDetector.match` (precomputed) and dtaidistance's
   subsequence DTW with its warping path, on the same problem in the same run.
   dtaidistance's C version is the fair opponent; its pure-Python version is listed too.
   Requirement: `match` at least 3x faster than dtaidistance (C).
2. One UMC tick with 3 models: window push, DTW bank with acceptance, likelihoods,
   posteriors and, when `controller.decision.expected_utility` is present, the decision.
   Requirement: p99 <= 25 us. Timed with the garbage collector disabled, as a
   real-time loop should run (gc.freeze() after start-up, gc.disable() in the loop);
   the load average is printed because other processes on the machine show up in p99.
"""

from __future__ import annotations

import gc
import os
import time
from collections.abc import Callable

import numpy as np
from dtaidistance import dtw_ndim
from dtaidistance.subsequence.dtw import subsequence_alignment

from controller.intent.onset import ModelBank, ObservationWindow, OnsetDetector, match
from controller.intent.posteriors import IntentEstimator


def _times_us(fn: Callable[[], object], n: int) -> np.ndarray:
    out = np.empty(n)
    clock = time.perf_counter_ns
    for i in range(n):
        t0 = clock()
        fn()
        out[i] = clock() - t0
    return out / 1e3


def _problem(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Three smooth 51-sample models and their covariances, like fitted PPCA models."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 0.5, 51)
    means = np.stack(
        [np.column_stack([a * np.sin(np.pi * s), b * np.sin(np.pi * s)])
         for a, b in ((1.6, 1.6), (1.4, 0.9), (0.9, 1.4))]
    )
    a = rng.normal(size=(3, 51, 2, 2)) * 0.05
    covs = a @ a.transpose(0, 1, 3, 2) + 2e-3 * np.eye(2)
    return means, covs, rng.normal(size=(200, 2)) * 0.01


def main() -> None:
    """Time everything and print two small tables."""
    means, covs, noise = _problem()
    obs = np.ascontiguousarray(means[0, 5:35] + noise[:30])
    mean, cov = means[0], covs[0]

    det = OnsetDetector(mean, cov)
    det.warm_up()
    match(obs, mean, cov)

    def dtai(use_c: bool) -> float:
        sa = subsequence_alignment(obs, mean, penalty=0.0, use_c=use_c)
        best = sa.best_match(minlength=1)
        _ = best.path
        return float(best.distance)

    dtai(True)
    dtai(False)
    n = 3000
    rows = [
        ("onset.match (one-shot)", float(np.median(_times_us(lambda: match(obs, mean, cov), n)))),
        ("OnsetDetector.match", float(np.median(_times_us(lambda: det.match(obs), n)))),
        ("dtaidistance subseq + path, C", float(np.median(_times_us(lambda: dtai(True), n)))),
        ("dtaidistance subseq + path, Python",
         float(np.median(_times_us(lambda: dtai(False), 200)))),
    ]
    ref = rows[2][1]
    print("One match, 30 observations x 51 model samples (median of runs)")
    print(f"{'method':<38}{'us':>10}{'dtai C / this':>16}")
    for name, us in rows:
        print(f"{name:<38}{us:>10.1f}{ref / us:>16.2f}")
    eye = np.tile(np.eye(2), (51, 1, 1))
    d_ours = match(obs, mean, eye).D
    d_dtai, _ = dtw_ndim.warping_paths(obs, mean, psi=(30, 0, 51, 51), keep_int_repr=True)
    print(f"check with identity covariances: D = {d_ours:.6g}, dtaidistance "
          f"(squared, same relaxation) = {d_dtai:.6g}")
    speedup = ref / rows[0][1]
    print(f"requirement match >= 3x faster than dtaidistance C: "
          f"{'PASS' if speedup >= 3 else 'FAIL'} ({speedup:.1f}x)\n")

    bank = ModelBank(means, covs)
    bank.warm_up()
    intent = IntentEstimator()
    intent.warm_up()
    window = ObservationWindow(30)
    stream = np.concatenate([means[0, :51], means[0, ::-1]]) + np.resize(noise, (102, 2))
    for q in stream[:30]:
        window.push(float(q[0]), float(q[1]))
    try:
        from controller.decision import expected_utility as decision
    except ImportError:  # decision is optional for this benchmark
        decision = None  # type: ignore[assignment]
    table = -np.random.default_rng(1).random((4, 4, 101)) * 100.0
    eu = np.zeros(4)
    if decision is not None:
        decision.warm_up()
    k = [0]

    def tick_core() -> None:
        bank.evaluate(window.view())
        intent.update(bank.D, bank.L, bank.accepted)

    def tick_full() -> None:
        q = stream[k[0] % 102]
        k[0] += 1
        window.push(float(q[0]), float(q[1]))
        bank.evaluate(window.view())
        post = intent.update(bank.D, bank.L, bank.accepted)
        if decision is not None:
            decision.decide_fast(table, bank.s_curr, post, eu)

    n_ticks = 50000
    load = os.getloadavg()[0]
    print(f"UMC tick with 3 models (microseconds, {n_ticks} ticks, gc disabled, "
          f"load average {load:.2f} on {os.cpu_count()} cores)")
    print(f"{'part':<44}{'p50':>8}{'p99':>8}{'max':>9}")
    results = {}
    gc.collect()
    gc.disable()
    for name, fn in (
        ("DTW bank + acceptance", bank_only := (lambda: bank.evaluate(window.view()))),
        ("DTW + likelihood + posteriors", tick_core),
        ("push + DTW + posteriors" + (" + decision" if decision else ""), tick_full),
    ):
        t = _times_us(fn, n_ticks)
        results[name] = t
        p50, p99 = np.percentile(t, [50, 99])
        print(f"{name:<44}{p50:>8.2f}{p99:>8.2f}{t.max():>9.1f}")
    gc.enable()
    del bank_only
    p99_full = float(np.percentile(list(results.values())[-1], 99))
    print(f"requirement full tick p99 <= 25 us: {'PASS' if p99_full <= 25 else 'FAIL'} "
          f"({p99_full:.1f} us)")


if __name__ == "__main__":
    main()
