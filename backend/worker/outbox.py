"""The worker's outbox: ticks and answers to the server, in order, off the loop thread.

Ticks are handed to a sender thread through a bounded buffer, so a server that reads
slowly costs memory up to a limit, then drops (and counts) records, never time.
"""

from __future__ import annotations

import collections
import threading
from multiprocessing.connection import Connection

from backend.worker.messages import TickBatch, WorkerMessage
from controller.tick_record import TickRecord

#: Records kept for the server if it stops reading: one minute at 100 Hz.
OUTBOX_LIMIT = 6000
BATCH_INTERVAL_S = 0.02


class Outbox:
    """Hands records from the loop to the pipe on a separate thread, packed into one
    block per batch (`TickBatch`). The loop thread only appends a record; packing and
    pickling happen on this thread, outside the lock the loop takes."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self.records: list[TickRecord] = []
        # Control messages, and the records queued before each of them as
        # (run token, records) still to be packed, in the order they must go out.
        self.messages: collections.deque[WorkerMessage | tuple[int, list[TickRecord]]] = (
            collections.deque())
        self.dropped = 0
        self.broken = threading.Event()
        self.stop = threading.Event()
        self.run_token = 0
        self._unsent = 0  # records put and not yet written to the pipe
        self._lock = threading.Lock()
        self.thread = threading.Thread(target=self._run, name="worker-outbox", daemon=True)

    def put_record(self, record: TickRecord) -> None:
        with self._lock:
            if len(self.records) >= OUTBOX_LIMIT:
                del self.records[0]
                self.dropped += 1
            else:
                self._unsent += 1
            self.records.append(record)

    def backlog(self) -> int:
        """Records waiting for the server (queued here or being written)."""
        with self._lock:
            return self._unsent

    def put(self, message: WorkerMessage) -> None:
        # Control messages go out after the records queued before them, so a RunStarted
        # is never overtaken by ticks of the run it announces (flush first).
        with self._lock:
            if self.records:
                self.messages.append((self.run_token, self.records))
                self.records = []
            self.messages.append(message)

    def _drain(self) -> list[WorkerMessage]:
        with self._lock:
            taken = list(self.messages)
            self.messages.clear()
            if self.records:
                taken.append((self.run_token, self.records))
                self.records = []
        return [TickBatch.from_records(*m) if isinstance(m, tuple) else m for m in taken]

    def _run(self) -> None:
        while not self.stop.is_set():
            self.flush()
            self.stop.wait(BATCH_INTERVAL_S)
        self.flush()

    def flush(self) -> None:
        if self.broken.is_set():
            return
        for msg in self._drain():
            try:
                self.conn.send(msg)
            except (BrokenPipeError, EOFError, OSError):
                self.broken.set()
                return
            if isinstance(msg, TickBatch):
                with self._lock:
                    self._unsent -= len(msg)
