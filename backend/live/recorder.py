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
from typing import Any

import numpy as np
from sqlalchemy import Connection, Engine, insert, update

from backend.core.resources import version
from backend.db.models import TICK_DATA_COLUMNS, Run, ticks_table
from backend.worker.messages import TIME_LIMIT_REACHED, RunStarted, TickBatch
from controller.tick_codec import FIELD_NAMES, TICK_DTYPE, TickBlock, db_rows

log = logging.getLogger(__name__)


def _sqlite_layout() -> np.dtype[np.void]:
    """A block's layout with each boolean field read as a 0/1 byte. The sqlite3 module
    binds an exact `int` as it is but sends a `bool` through its adapter lookup (a
    failed attribute lookup per value): the nine boolean fields were more than half the
    cost of inserting a tick. SQLite stores the same 0 or 1 either way (a BOOLEAN column
    holds an integer)."""
    fields = TICK_DTYPE.fields
    assert fields is not None  # a structured dtype
    return np.dtype({
        "names": list(FIELD_NAMES),
        "formats": [np.uint8 if fields[n][0] == np.bool_ else fields[n][0]
                    for n in FIELD_NAMES],
        "offsets": [fields[n][1] for n in FIELD_NAMES],
        "itemsize": TICK_DTYPE.itemsize,
    })


_SQLITE_ROW = _sqlite_layout()


def sqlite_rows(block: TickBlock) -> list[tuple[Any, ...]]:
    """A block's rows for SQLite's driver, in `FIELD_NAMES` order: the values of
    `tick_codec.db_rows(block, nan_as_null=False)` (SQLite stores a bound NaN as NULL by
    itself), with booleans as the integers 0 and 1 (`_sqlite_layout`)."""
    if block.dtype != TICK_DTYPE:  # not a block of this version's layout: the codec's rows
        return db_rows(block, nan_as_null=False)
    rows: list[tuple[Any, ...]] = block.view(_SQLITE_ROW).tolist()
    return rows


def _summarise(config: dict[str, object]) -> dict[str, object]:
    """The run's configuration without inline model and utility documents (the trial
    keeps those by reference); their versions are kept."""
    out = dict(config)
    out["exostudy_version"] = version()
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
        self._pending: list[tuple[int, TickBlock]] = []  # (runs.id, ticks), in order
        self._pending_n = 0
        self._lock = threading.Lock()
        self._flush_lock = threading.Lock()
        self._runs: dict[int, int] = {}  # worker run token -> runs.id, for the current worker
        self._counts: dict[int, int] = {}
        self.current_run_id: int | None = None
        self.written = 0
        self.failures = 0
        self.last_error = ""
        self._sql: dict[int, str] = {}
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
                # Whole only if every sample the worker made for it is stored: none
                # dropped by the worker's outbox or this backlog, none still unwritten.
                whole = (msg.limit_reached is not None
                         and self._counts.get(self.current_run_id, 0) == msg.limit_reached)
                self._close(conn, self.current_run_id,
                            TIME_LIMIT_REACHED if whole else "controller changed")
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
                self.dropped += len(batch)
                return
            if len(batch):
                self._pending.append((run_id, batch.ticks))
                self._pending_n += len(batch)
                self._trim()

    def _trim(self) -> None:
        """Drop the oldest pending ticks beyond the limit (call with `_lock` held)."""
        excess = self._pending_n - self.backlog_limit
        while excess > 0 and self._pending:
            run_id, block = self._pending[0]
            cut = min(excess, len(block))
            if cut == len(block):
                del self._pending[0]
            else:
                self._pending[0] = (run_id, block[cut:])
            self._pending_n -= cut
            self.dropped += cut
            excess -= cut

    @property
    def backlog(self) -> int:
        """Ticks received and not yet written."""
        return self._pending_n

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
            pending_n, self._pending_n = self._pending_n, 0
        if not pending:
            return 0
        # Rows go to the driver as plain tuples (`tick_codec.db_rows`, NaN as NULL), one
        # executemany per run: building a dict per row and SQLAlchemy's per-value
        # processing cost more than the database's insert itself. SQLite stores a bound
        # NaN as NULL by itself, so it is spared the per-value pass (`sqlite_rows`).
        sqlite = self.engine.dialect.name == "sqlite"
        written: Counter[int] = Counter()
        try:
            with self.engine.begin() as conn:
                for run_id, blocks in _by_run(pending):
                    rows = [r for b in blocks
                            for r in (sqlite_rows(b) if sqlite else db_rows(b))]
                    conn.exec_driver_sql(self._insert_sql(run_id), rows)
                    written[run_id] += len(rows)
        except Exception as exc:
            # Keep the ticks for the next attempt rather than lose them.
            self.failures += 1
            self.last_error = str(exc)[:300]
            log.exception("writing %d ticks failed", pending_n)
            with self._lock:
                self._pending = pending + self._pending
                self._pending_n += pending_n
                self._trim()
            return 0
        self.last_error = ""
        for run_id, n in written.items():
            self._counts[run_id] = self._counts.get(run_id, 0) + n
        self.written += pending_n
        return pending_n

    def _insert_sql(self, run_id: int) -> str:
        """The driver-level INSERT of one tick row of run `run_id` (an integer the
        server made, written into the statement so rows need no extra value), in the
        driver's parameter style."""
        sql = self._sql.get(run_id)
        if sql is None:
            mark = "?" if self.engine.dialect.paramstyle == "qmark" else "%s"
            quote = self.engine.dialect.identifier_preparer.quote  # "trigger" is a keyword
            cols = ", ".join(quote(c) for c in ("run_id", *TICK_DATA_COLUMNS))
            marks = ", ".join([str(int(run_id))] + [mark] * len(TICK_DATA_COLUMNS))
            sql = f"INSERT INTO {ticks_table.name} ({cols}) VALUES ({marks})"
            self._sql = {run_id: sql}  # one run at a time: keep the last
        return sql

    def _run(self) -> None:
        # On a fixed schedule: a slow write does not stretch the time the next ticks
        # wait in memory (what a killed server loses).
        due = time.monotonic() + self.flush_interval
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            self.flush()
            due = max(due + self.flush_interval, time.monotonic())


def _by_run(pending: list[tuple[int, TickBlock]]) -> list[tuple[int, list[TickBlock]]]:
    """Consecutive blocks of the same run grouped, in order."""
    out: list[tuple[int, list[TickBlock]]] = []
    for run_id, block in pending:
        if out and out[-1][0] == run_id:
            out[-1][1].append(block)
        else:
            out.append((run_id, [block]))
    return out
