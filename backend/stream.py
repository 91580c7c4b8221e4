"""Fans ticks out to browser consoles without ever pushing back on the worker.

The supervisor's reader thread appends ticks to a deque (never blocks). An asyncio task
turns them into one JSON message at `stream_rate` Hz, encoded once and put on every
client's bounded queue; a full queue drops its oldest message, so a slow tab only
loses its own updates.
"""

from __future__ import annotations

import asyncio
import collections
import json
import math
import time
from dataclasses import dataclass, field
from typing import Any

from backend.schemas.live import STREAM_FIELDS
from controller.tick import TickRecord

_FIELD_INDEX = [TickRecord.field_names().index(f) for f in STREAM_FIELDS]


def _clean(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


@dataclass(eq=False)
class LiveClient:
    """One connected console."""

    queue: asyncio.Queue[str]
    dropped: int = 0
    msg_seq: int = 0
    connected_at: float = field(default_factory=time.time)

    def offer(self, message: str) -> None:
        """Queue a message, dropping the oldest one if the client has fallen behind."""
        while self.queue.full():
            try:
                self.queue.get_nowait()
                self.dropped += 1
            except asyncio.QueueEmpty:
                break
        self.queue.put_nowait(message)


class LiveStream:
    """Thread-safe ingest, asyncio fan-out."""

    def __init__(self, rate_hz: float = 30.0, queue_size: int = 60) -> None:
        self.rate_hz = rate_hz
        self.queue_size = queue_size
        self._incoming: collections.deque[TickRecord] = collections.deque(maxlen=10_000)
        self._clients: set[LiveClient] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._task: asyncio.Task[None] | None = None
        self.run_id: int | None = None
        self.sent = 0

    @property
    def client_count(self) -> int:
        """Connected consoles."""
        return len(self._clients)

    def push(self, records: tuple[TickRecord, ...] | list[TickRecord]) -> None:
        """Called from any thread; O(len(records)), never blocks."""
        if self._clients:
            self._incoming.extend(records)

    async def start(self) -> None:
        """Start the periodic sender on the running loop."""
        self._loop = asyncio.get_running_loop()
        self._task = asyncio.create_task(self._pump(), name="live-stream")

    async def stop(self) -> None:
        """Stop the sender."""
        if self._task is not None:
            self._task.cancel()
            try:
                await self._task
            except asyncio.CancelledError:
                pass

    def connect(self) -> LiveClient:
        """Register a console (on the event loop)."""
        client = LiveClient(queue=asyncio.Queue(maxsize=self.queue_size))
        self._clients.add(client)
        return client

    def disconnect(self, client: LiveClient) -> None:
        """Forget a console."""
        self._clients.discard(client)

    def broadcast_json(self, payload: dict[str, Any]) -> None:
        """Send a control message (status) to every console; thread-safe."""
        text = json.dumps(payload, allow_nan=False, default=str)
        if self._loop is None:
            return
        try:
            self._loop.call_soon_threadsafe(self._offer_all, text)
        except RuntimeError:
            pass  # loop closed during shutdown

    def _offer_all(self, text: str) -> None:
        for c in list(self._clients):
            c.offer(text)

    def _take(self) -> list[TickRecord]:
        out: list[TickRecord] = []
        try:
            while True:
                out.append(self._incoming.popleft())
        except IndexError:
            return out

    async def _pump(self) -> None:
        period = 1.0 / self.rate_hz
        next_t = time.monotonic()
        while True:
            next_t += period
            await asyncio.sleep(max(0.0, next_t - time.monotonic()))
            if time.monotonic() - next_t > 1.0:
                next_t = time.monotonic()  # resynchronise after a stall instead of bursting
            records = self._take()
            if not records or not self._clients:
                continue
            # The columns are the same for everyone; only msg_seq/dropped differ.
            rows = [r.as_tuple() for r in records]
            columns = {
                name: [_clean(row[i]) for row in rows]
                for name, i in zip(STREAM_FIELDS, _FIELD_INDEX, strict=True)
            }
            body = json.dumps(columns, allow_nan=False, separators=(",", ":"))
            now = time.time()
            for c in list(self._clients):
                c.msg_seq += 1
                head = (
                    f'{{"type":"ticks","msg_seq":{c.msg_seq},"sent_at":{now:.6f},'
                    f'"run_id":{json.dumps(self.run_id)},"dropped":{c.dropped},"columns":'
                )
                c.offer(head + body + "}")
                self.sent += 1
