"""How often a replication verdict changes between two disjoint sets of seeds, as the
number of seeds per set grows: the measurement behind the default `--seeds` of
`exostudy replicate` (docs/replication.md, "How many seeds").

Step 1 measures every seed once with the cohort engine (`protocol_seed` and
`measure_seed`, the paper's protocol, 8 participants, 3 with the E-UMC) and keeps each
seed's measures in a cache file, so the sweep can be repeated without simulating again
(about 7-15 s per seed on 2 shared cores). Step 2 draws, for each set size k, `draws`
pairs of disjoint k-seed sets from the pool, judges every claim on each set
(`controller.evaluation.paper_claims.judge`) and counts the claims whose verdicts
differ. The same is done with the former rule (the paper's mean against the virtual
interval, treating the paper's number as exact) for the claims that are now judged on
the difference, for comparison.

    .venv/bin/python bench/bench_verdict_stability.py [--seeds 60] [--sizes 2,3,...]
        [--draws 100] [--cache bench/results/verdict_stability/seeds.json]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.record import load_average, record  # noqa: E402
from controller.evaluation.paper_claims import CLAIMS, Claim, judge  # noqa: E402

CACHE = ROOT / "bench" / "results" / "verdict_stability" / "seeds.json"


def measure(seeds: list[int], cache: Path) -> dict[int, dict[str, float]]:
    """Every seed's measures (the cached ones read, the others simulated and added)."""
    from controller.evaluation.paper_protocol import measure_seed, protocol_seed

    keep = {c.measure for c in CLAIMS if c.measure}
    doc: dict[str, dict[str, float | None]] = (json.loads(cache.read_text())
                                               if cache.is_file() else {})
    for s in seeds:
        if str(s) in doc:
            continue
        t0 = time.monotonic()
        trials, models, _u = protocol_seed(s, participants=8, eumc=3, data_participants=6)
        m = measure_seed(trials, models)
        doc[str(s)] = {k: (v if math.isfinite(v) else None) for k, v in m.items()
                       if k in keep}
        cache.parent.mkdir(parents=True, exist_ok=True)
        cache.write_text(json.dumps(doc, indent=0, sort_keys=True) + "\n")
        print(f"seed {s}: {time.monotonic() - t0:.1f} s", flush=True)
    return {int(s): {k: (math.nan if v is None else float(v)) for k, v in m.items()}
            for s, m in doc.items() if int(s) in seeds}


def verdicts(claims: list[Claim], measures: list[dict[str, float]]) -> list[str]:
    """The verdict of each claim on one set of seeds."""
    return [judge(c, [m.get(c.measure, math.nan) for m in measures]).verdict.value
            for c in claims]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=60, help="pool of seeds 1..N")
    ap.add_argument("--sizes", default="2,3,4,5,6,8,10,12,15,20,25,30")
    ap.add_argument("--draws", type=int, default=100, help="pairs of disjoint sets per size")
    ap.add_argument("--cache", type=Path, default=CACHE)
    args = ap.parse_args()
    load_before = load_average()
    pool = measure(list(range(1, args.seeds + 1)), args.cache)
    seeds = sorted(pool)
    # Claims that depend on the seeds (method checks and questionnaires do not).
    claims = [c for c in CLAIMS if c.kind in ("difference", "value", "ordinal")]
    table = [c for c in claims if c.kind == "difference"]
    former = [replace(c, kind="value") for c in table]
    rng = np.random.default_rng(20261127)
    rows: list[list[object]] = []
    per_claim: dict[int, np.ndarray] = {}
    print(f"| seeds per set | claims that flip (mean of {len(claims)} judged) | no claim "
          f"flips | table claims that flip (of {len(table)}) | the same, former rule |")
    print("| --- | --- | --- | --- | --- |")
    for k in (int(s) for s in args.sizes.split(",")):
        if 2 * k > len(seeds):
            break
        flips = np.zeros((args.draws, len(claims)), dtype=bool)
        old = np.zeros((args.draws, len(former)), dtype=bool)
        for r in range(args.draws):
            pick = rng.permutation(seeds)[:2 * k]
            a = [pool[int(s)] for s in pick[:k]]
            b = [pool[int(s)] for s in pick[k:]]
            flips[r] = np.array(verdicts(claims, a)) != np.array(verdicts(claims, b))
            old[r] = np.array(verdicts(former, a)) != np.array(verdicts(former, b))
        per_claim[k] = flips.mean(axis=0)
        n_flip = flips.sum(axis=1)
        t_idx = [claims.index(c) for c in table]
        row = [k, f"{n_flip.mean():.2f}", f"{(n_flip == 0).mean():.2f}",
               f"{flips[:, t_idx].sum(axis=1).mean():.2f}", f"{old.sum(axis=1).mean():.2f}"]
        print("| " + " | ".join(str(c) for c in row) + " |", flush=True)
        rows.append(row)
    print("\nPer claim: share of draws in which the verdict flips")
    print("| claim | " + " | ".join(f"k={k}" for k in per_claim) + " |")
    for i, c in enumerate(claims):
        print(f"| {c.key} | " + " | ".join(f"{per_claim[k][i]:.2f}" for k in per_claim)
              + " |")
    record("verdict_stability", "bench/bench_verdict_stability.py " + " ".join(sys.argv[1:]),
           ["seeds per set", f"claims that flip (mean of {len(claims)} judged)",
            "share of draws with no flip", f"table claims that flip (of {len(table)})",
            "the same, former rule"], rows, load_before,
           note=f"{args.draws} random pairs of disjoint seed sets per size, drawn from seeds "
           f"1-{len(seeds)} of the cohort engine (paper protocol: 8 participants, 3 with "
           "the E-UMC). A flip: the two sets give a claim different verdicts.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
