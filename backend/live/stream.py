"""Fans ticks out to browser consoles without ever pushing back on the worker.

The supervisor's reader thread appends each batch of ticks from the worker to a deque
(never blocks) and wakes an asyncio task. That task sends what has arrived at once, as
one JSON message encoded once for every client, within a budget of `stream_rate`
messages per second (a token bucket that lets a message go early after a longer gap, so
the jitter of the worker's batches costs no waiting). Over budget, it waits for the next
token and sends everything gathered by then in one message. A sample therefore waits in
the server only when batches come faster than `stream_rate` on average (the worker hands
over a batch about every 20 ms), never for a timer of its own. Each client has a bounded
queue; a full queue drops its oldest message, so a slow tab only loses its own updates.
"""

from __future__ import annotations

import asyncio
import collections
import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from backend.schemas.live import STREAM_FIELDS
from controller.tick_codec import TickBlock, json_columns

#: Ticks kept for the consoles while the sender is behind (the oldest go first).
_INCOMING_LIMIT = 10_000
#: Longest wait for a wake-up before looking anyway (a lost wake-up costs at most this).
_IDLE_CHECK_S = 0.5
#: Messages that may go out back to back after a quiet spell (token bucket depth).
_BURST = 2.0


def encode_columns(ticks: TickBlock) -> str:
    """The `columns` object of a `LiveTicks` message: one array per streamed field."""
    return json.dumps(json_columns(ticks, STREAM_FIELDS), allow_nan=False,
                      separators=(",", ":"))


@dataclass(eq=False)
class LiveClient:
    """One connected console."""

    queue: asyncio.Queue[str]
    #: A browser's WebSocket (counted in health), not an in-process follower such as
    #: the 3D view's pose updater, which stays subscribed with no browser connected.
    console: bool = True
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
        # Blocks of ticks not yet sent, at most `_INCOMING_LIMIT` ticks (oldest dropped).
        self._incoming: collections.deque[TickBlock] = collections.deque()
        self._incoming_n = 0
        self._incoming_lock = threading.Lock()
        self._clients: set[LiveClient] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._task: asyncio.Task[None] | None = None
        self._wake: asyncio.Event | None = None
        self._wake_pending = False
        self.run_id: int | None = None
        self.sent = 0
        self.messages = 0

    @property
    def client_count(self) -> int:
        """Open console connections (in-process followers are not consoles)."""
        return sum(1 for c in self._clients if c.console)

    def push(self, ticks: TickBlock) -> None:
        """Called from any thread; never blocks (for long)."""
        if not self._clients or not len(ticks):
            return
        with self._incoming_lock:
            self._incoming.append(ticks)
            self._incoming_n += len(ticks)
            while self._incoming_n - len(self._incoming[0]) >= _INCOMING_LIMIT:
                self._incoming_n -= len(self._incoming.popleft())
        # One wake-up per quiet period: the flag is cleared by the sender before it takes
        # the records, so records appended after that always schedule another wake-up.
        if self._wake_pending or self._loop is None or self._wake is None:
            return
        self._wake_pending = True
        try:
            self._loop.call_soon_threadsafe(self._wake.set)
        except RuntimeError:
            pass  # loop closed during shutdown

    async def start(self) -> None:
        """Start the sender on the running loop."""
        self._loop = asyncio.get_running_loop()
        self._wake = asyncio.Event()
        self._task = asyncio.create_task(self._pump(), name="live-stream")

    async def stop(self) -> None:
        """Stop the sender."""
        if self._task is not None:
            self._task.cancel()
            try:
                await self._task
            except asyncio.CancelledError:
                pass

    def call_soon(self, callback: Callable[[], None]) -> bool:
        """Run `callback` on the stream's event loop, from any thread (the worker's
        callbacks hand their answers to the routes waiting there). False before `start`
        or once the loop has closed: nobody is waiting then."""
        if self._loop is None:
            return False
        try:
            self._loop.call_soon_threadsafe(callback)
        except RuntimeError:
            return False  # loop closed during shutdown
        return True

    def connect(self, console: bool = True) -> LiveClient:
        """Register a console's connection, or (`console` false) an in-process
        follower; on the event loop."""
        client = LiveClient(queue=asyncio.Queue(maxsize=self.queue_size), console=console)
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

    def _take(self) -> TickBlock | None:
        with self._incoming_lock:
            blocks = list(self._incoming)
            self._incoming.clear()
            self._incoming_n = 0
        if not blocks:
            return None
        return blocks[0] if len(blocks) == 1 else np.concatenate(blocks)

    async def _pump(self) -> None:
        assert self._wake is not None
        wake = self._wake
        rate = self.rate_hz
        tokens = _BURST
        refilled = time.monotonic()
        while True:
            try:
                await asyncio.wait_for(wake.wait(), _IDLE_CHECK_S)
            except TimeoutError:
                pass
            wake.clear()
            now = time.monotonic()
            tokens = min(_BURST, tokens + (now - refilled) * rate)
            refilled = now
            if tokens < 1.0:  # over budget: wait for the next token, gathering more ticks
                await asyncio.sleep((1.0 - tokens) / rate)
                tokens = 1.0
                refilled = time.monotonic()
            self._wake_pending = False
            ticks = self._take()
            if ticks is None or not self._clients:
                continue
            tokens -= 1.0
            self._send(ticks)

    def _send(self, ticks: TickBlock) -> None:
        # The columns are the same for everyone; only msg_seq/dropped differ.
        body = encode_columns(ticks)
        run_id = json.dumps(self.run_id)
        now = time.time()
        self.messages += 1
        for c in list(self._clients):
            c.msg_seq += 1
            head = (
                f'{{"type":"ticks","msg_seq":{c.msg_seq},"sent_at":{now:.6f},'
                f'"run_id":{run_id},"dropped":{c.dropped},"columns":'
            )
            c.offer(head + body + "}")
            self.sent += 1
