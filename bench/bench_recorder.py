"""How fast the tick recorder stores ticks in SQLite (what bounds the virtual study's
speed-up: it runs the simulated exoskeleton many times faster than real time).

Baseline in the same run: the same rows, already built as tuples with the run id as
their first value, inserted with the sqlite3 module's executemany alone. The recorder
gets the ticks as the worker sends them, packed in one block (`TickBatch`; packing is
the worker's cost, `bench/bench_tick_transport.py`), writes the run id into the
statement and leaves NaN to SQLite (stored as NULL), so it can beat that baseline.

    .venv/bin/python bench/bench_recorder.py
"""

from __future__ import annotations

import math
import os
import sqlite3
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from backend.db import migrate  # noqa: E402
from backend.db.engine import make_engine  # noqa: E402
from backend.db.models import TICK_DATA_COLUMNS  # noqa: E402
from backend.live.recorder import TickRecorder  # noqa: E402
from backend.worker.messages import RunStarted, TickBatch  # noqa: E402
from controller.tick_record import TickRecord  # noqa: E402

N = 5000
REPEATS = 5


def _records() -> tuple[TickRecord, ...]:
    return tuple(TickRecord(seq=k, t=k / 100, t_host=1.7e9 + k / 100, q_left=0.3 * math.sin(k),
                            q_right=0.2, post_squat=0.4, post_other=0.6, lock_left=k % 50 < 10,
                            truth_activity="squat") for k in range(N))


def main() -> None:
    recs = _records()
    with tempfile.TemporaryDirectory() as d:
        url = f"sqlite:///{d}/rec.db"
        migrate.upgrade(url)
        engine = make_engine(url)
        rec = TickRecorder(engine)
        run_id = rec.run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
        best_rec = math.inf
        for _ in range(REPEATS):
            rec.add(TickBatch.from_records(1, recs))
            t0 = time.perf_counter()
            assert rec.flush() == N
            best_rec = min(best_rec, time.perf_counter() - t0)
        engine.dispose()

        rows = [(run_id, *[None if v != v else v for v in r.as_tuple()]) for r in recs]
        con = sqlite3.connect(f"{d}/rec.db")
        con.execute("PRAGMA journal_mode=WAL")
        con.execute("PRAGMA synchronous=NORMAL")
        cols = ", ".join(f'"{c}"' for c in ("run_id", *TICK_DATA_COLUMNS))
        marks = ", ".join(["?"] * (1 + len(TICK_DATA_COLUMNS)))
        sql = f"INSERT INTO ticks ({cols}) VALUES ({marks})"
        best_raw = math.inf
        for _ in range(REPEATS):
            t0 = time.perf_counter()
            con.executemany(sql, rows)
            con.commit()
            best_raw = min(best_raw, time.perf_counter() - t0)
        con.close()
    print(f"load average {os.getloadavg()[0]:.2f}; {N} ticks per flush, best of {REPEATS}")
    print(f"recorder (block -> rows -> SQLite):   {N / best_rec:9.0f} ticks/s")
    print(f"baseline (sqlite3 executemany only):  {N / best_raw:9.0f} ticks/s")
    print(f"recorder / baseline time: {best_rec / best_raw:.2f}x")


if __name__ == "__main__":
    main()
