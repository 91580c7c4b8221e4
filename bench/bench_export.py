"""Export of a 10-minute trial (60,000 ticks) as CSV, against a baseline in the same run.

Baseline: `SELECT *` of the same rows through the same connection with no formatting, so
the ratio shows what the CSV writing itself costs. Target: export under 1 s.

    .venv/bin/python bench/bench_export.py
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sqlalchemy import select

from backend.analysis import tick_queries
from backend.db import migrate
from backend.db.engine import make_engine
from backend.db.models import ticks_table
from backend.live.recorder import TickRecorder
from backend.worker.messages import RunStarted, TickBatch
from controller.tick_record import TickRecord

N = 60_000


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        url = f"sqlite:///{d}/bench.db"
        migrate.upgrade(url)
        engine = make_engine(url)
        rec = TickRecorder(engine)
        run_id = rec.run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
        t0 = time.perf_counter()
        for start in range(0, N, 100):  # one second of ticks per batch, as live
            rec.add(TickBatch.from_records(1, tuple(
                TickRecord(seq=k, t=k / 100, q_left=0.5, q_right=0.4, omega_left=1.0,
                           post_squat=0.7, post_other=0.3, action=2, lock_left=k % 7 == 0,
                           torque_left=3.2, d_squat=12.5, l_squat=31)
                for k in range(start, start + 100))))
            rec.flush()
        write_s = time.perf_counter() - t0
        export, baseline = [], []
        for _ in range(5):
            t0 = time.perf_counter()
            with engine.connect() as conn:
                rows = conn.execute(select(ticks_table).where(ticks_table.c.run_id == run_id)
                                    .order_by(ticks_table.c.id)).all()
            baseline.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            text = tick_queries.csv_text(engine, run_id)
            export.append(time.perf_counter() - t0)
        assert len(rows) == N and text.count("\n") == N + 1
        b, e = statistics.median(baseline), statistics.median(export)
        print(f"ticks stored: {N} in 600 one-second batches, {write_s:.2f} s "
              f"({write_s / 600 * 1e3:.1f} ms per batch)")
        print(f"SELECT only (baseline):  median {b:.3f} s")
        print(f"CSV export:              median {e:.3f} s  ({e / b:.2f}x baseline; "
              f"target < 1 s: {'PASS' if e < 1.0 else 'FAIL'})")
        print(f"CSV size: {len(text) / 1e6:.1f} MB")
        engine.dispose()


if __name__ == "__main__":
    main()
