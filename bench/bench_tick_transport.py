"""What one tick costs between the worker's loop and the database row, per form.

A sped-up virtual study is bounded by the server: it must receive, store and fan out
every tick the worker produces (6,000 to 10,000 a second at 100x). The profile of the
default study before this change put the largest share of the server's time in
unpickling `TickRecord` dataclasses one at a time, then turning each back into a row.

Two paths over the same 200-tick batches (a batch is what the worker's outbox sends
every 20 ms at 100x), in one run:

- baseline, records: the worker pickles a tuple of records, the server unpickles it and
  builds a row tuple per record with NaN mapped to None (the path before);
- block: the worker packs the records into one structured array
  (`controller.tick_codec.pack`), pickles it, the server unpickles one buffer and gets
  the rows with `db_rows` (SQLite's own NaN-as-NULL, as the recorder does).

Reported per tick, split into the worker's side and the server's side, best of 5.

    .venv/bin/python bench/bench_tick_transport.py
"""

from __future__ import annotations

import math
import pickle
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from controller.tick_codec import db_rows, pack  # noqa: E402
from controller.tick_record import TickRecord  # noqa: E402

BATCH = 200
BATCHES = 50
REPEATS = 5


def _records() -> list[TickRecord]:
    return [TickRecord(seq=k, t=k / 100, t_host=1.7e9 + k / 100, q_raw_left=0.3 * math.sin(k),
                       q_left=0.3 * math.sin(k), q_right=0.2, omega_left=0.1, post_squat=0.4,
                       post_other=0.6, lock_left=k % 50 < 10, truth_activity="squat")
            for k in range(BATCH)]


def _best(fn: Callable[[], Any]) -> float:
    best = math.inf
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        for _ in range(BATCHES):
            fn()
        best = min(best, time.perf_counter() - t0)
    return best / (BATCHES * BATCH) * 1e6  # us per tick


def main() -> None:
    records = _records()
    as_tuple = tuple(records)
    old_wire = pickle.dumps(as_tuple, pickle.HIGHEST_PROTOCOL)
    new_wire = pickle.dumps(pack(records), pickle.HIGHEST_PROTOCOL)

    def old_server() -> None:
        got = pickle.loads(old_wire)
        [(1, *[None if v != v else v for v in r.as_tuple()]) for r in got]

    def new_server() -> None:
        db_rows(pickle.loads(new_wire), nan_as_null=False)

    old_worker = _best(lambda: pickle.dumps(as_tuple, pickle.HIGHEST_PROTOCOL))
    new_worker = _best(lambda: pickle.dumps(pack(records), pickle.HIGHEST_PROTOCOL))
    old_srv, new_srv = _best(old_server), _best(new_server)
    print(f"{BATCH}-tick batches, best of {REPEATS} x {BATCHES}; us per tick")
    print("| path | worker: to bytes | server: bytes to row tuples | pipe bytes per tick |")
    print("| --- | --- | --- | --- |")
    print(f"| records (baseline) | {old_worker:.2f} | {old_srv:.2f} | "
          f"{len(old_wire) / BATCH:.0f} |")
    print(f"| block | {new_worker:.2f} | {new_srv:.2f} | {len(new_wire) / BATCH:.0f} |")
    print(f"server side: block takes {new_srv / old_srv:.2f}x the baseline's time "
          f"({old_srv / new_srv:.1f}x faster); worker side {new_worker / old_worker:.2f}x")


if __name__ == "__main__":
    main()
