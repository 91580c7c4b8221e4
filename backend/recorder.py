"""Writes the worker's ticks to the database in batches.

Ticks wait in memory at most `flush_interval` seconds (setting `db_flush_interval`,
at most 1 s), so a killed server loses at most that much. Each worker run becomes a
`runs` row; its ticks reference it.

While the database refuses writes (disk full, locked), ticks are kept for the next
attempt up to `backlog_limit`; beyond it the oldest are dropped and counted
(`dropped`), so memory stays bounded and the loss is visible in health. `last_error`
is cleared by the next successful write: health reports the present, `failures` and
`dropped` the history.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import Counter
from datetime import UTC, datetime

from sqlalchemy import Connection, Engine, insert, update

from backend.db.models import TICK_DATA_COLUMNS, Run, ticks_table
from backend.worker.messages import RunStarted, TickBatch
from controller.tick import TickRecord

log = logging.getLogger(__name__)


def _summarise(config: dict[str, object]) -> dict[str, object]:
    """The run's configuration without inline model and utility documents (the trial
    keeps those by reference); their versions are kept."""
    out = dict(config)
    for key in ("models", "utilities"):
        doc = out.get(key)
        if isinstance(doc, dict):
            out[key] = {"inline": True, "version": doc.get("version"),
                        "created": doc.get("created")}
    return out


class TickRecorder:
    """Buffers tick batches and inserts them on a background thread."""

    def __init__(self, engine: Engine, flush_interval: float = 0.5,
                 backlog_limit: int = 30_000) -> None:
        self.engine = engine
        self.flush_interval = flush_interval
        self.backlog_limit = backlog_limit
        self.dropped = 0
        self._pending: list[tuple[int, TickRecord]] = []
        self._lock = threading.Lock()
        self._flush_lock = threading.Lock()
        self._runs: dict[int, int] = {}  # worker run token -> runs.id, for the current worker
        self._counts: dict[int, int] = {}
        self.current_run_id: int | None = None
        self.written = 0
        self.failures = 0
        self.last_error = ""
        self._sql: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="tick-recorder", daemon=True)

    def start(self) -> None:
        """Begin flushing periodically."""
        self._thread.start()

    def stop(self) -> None:
        """Flush what is left and stop."""
        self._stop.set()
        self._thread.join(5.0)
        self.flush()

    def run_started(self, msg: RunStarted, device_kind: str) -> int:
        """Create the run row (closing the previous run of this worker)."""
        self.flush()
        with self.engine.begin() as conn:
            if self.current_run_id is not None:
                self._close(conn, self.current_run_id, "controller changed")
            result = conn.execute(
                insert(Run).values(
                    started_at=datetime.now(UTC),
                    device_kind=device_kind,
                    controller=msg.controller,
                    config_json=json.dumps(_summarise(msg.controller_config), default=str),
                    worker_pid=msg.pid,
                    tick_count=0,
                )
            )
            pk = result.inserted_primary_key
            run_id = int(pk[0]) if pk is not None else 0
        with self._lock:
            self._runs[msg.run_token] = run_id
            self.current_run_id = run_id
        return run_id

    def worker_exited(self, reason: str) -> None:
        """Store everything received, then close the run with the reason."""
        self.flush()
        with self.engine.begin() as conn:
            if self.current_run_id is not None:
                self._close(conn, self.current_run_id, reason)
        with self._lock:
            self._runs.clear()
            self.current_run_id = None

    def _close(self, conn: Connection, run_id: int, reason: str) -> None:
        conn.execute(
            update(Run)
            .where(Run.id == run_id)
            .values(ended_at=datetime.now(UTC), end_reason=reason[:200],
                    tick_count=self._counts.get(run_id, 0))
        )

    def add(self, batch: TickBatch) -> None:
        """Queue a batch (called on the supervisor's reader thread)."""
        with self._lock:
            run_id = self._runs.get(batch.run_token)
            if run_id is None:
                # Its run row could not be created (database down): counted as lost.
                log.warning("ticks for unknown run token %s dropped", batch.run_token)
                self.dropped += len(batch.records)
                return
            self._pending.extend((run_id, r) for r in batch.records)
            self._trim()

    def _trim(self) -> None:
        """Drop the oldest pending ticks beyond the limit (call with `_lock` held)."""
        excess = len(self._pending) - self.backlog_limit
        if excess > 0:
            del self._pending[:excess]
            self.dropped += excess

    @property
    def backlog(self) -> int:
        """Ticks received and not yet written."""
        return len(self._pending)

    def flush(self) -> int:
        """Insert everything pending now; returns the number of ticks written.

        Flushes are serialised: the periodic thread, a run change and an API request
        (stopping a recording) can all flush, and two overlapping inserts could commit
        in the wrong order, giving later ticks lower ids than earlier ones (ticks are
        read back in id order).
        """
        with self._flush_lock:
            return self._flush()

    def _flush(self) -> int:
        with self._lock:
            pending, self._pending = self._pending, []
        if not pending:
            return 0
        # NaN ("not computed at this tick") is stored as NULL on every database. Rows go
        # to the driver as plain tuples in one executemany: building a dict per row and
        # SQLAlchemy's per-value processing cost more than SQLite's insert itself.
        rows = [(run_id, *[None if v != v else v for v in r.as_tuple()])
                for run_id, r in pending]
        try:
            with self.engine.begin() as conn:
                conn.exec_driver_sql(self._insert_sql(), rows)
        except Exception as exc:
            # Keep the ticks for the next attempt rather than lose them.
            self.failures += 1
            self.last_error = str(exc)[:300]
            log.exception("writing %d ticks failed", len(rows))
            with self._lock:
                self._pending = pending + self._pending
                self._trim()
            return 0
        self.last_error = ""
        for run_id, n in Counter(run_id for run_id, _ in pending).items():
            self._counts[run_id] = self._counts.get(run_id, 0) + n
        self.written += len(rows)
        return len(rows)

    def _insert_sql(self) -> str:
        """The driver-level INSERT of one tick row, in the driver's parameter style."""
        if self._sql is None:
            mark = "?" if self.engine.dialect.paramstyle == "qmark" else "%s"
            quote = self.engine.dialect.identifier_preparer.quote  # "trigger" is a keyword
            cols = ", ".join(quote(c) for c in ("run_id", *TICK_DATA_COLUMNS))
            marks = ", ".join([mark] * (1 + len(TICK_DATA_COLUMNS)))
            self._sql = f"INSERT INTO {ticks_table.name} ({cols}) VALUES ({marks})"
        return self._sql

    def _run(self) -> None:
        # On a fixed schedule: a slow write does not stretch the time the next ticks
        # wait in memory (what a killed server loses).
        due = time.monotonic() + self.flush_interval
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            self.flush()
            due = max(due + self.flush_interval, time.monotonic())
