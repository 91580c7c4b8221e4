"""Fan-out to consoles: batching, NaN as null, a slow client only loses its own messages."""

from __future__ import annotations

import asyncio
import json

from backend.schemas.live import STREAM_FIELDS, LiveTicks
from backend.stream import LiveStream
from controller.tick import TickRecord


def test_slow_client_drops_oldest_and_fast_client_gets_all() -> None:
    async def scenario() -> tuple[list[dict], list[dict], int]:
        stream = LiveStream(rate_hz=100.0, queue_size=3)
        await stream.start()
        slow = stream.connect()
        fast = stream.connect()
        got_fast: list[dict] = []
        for i in range(10):
            stream.push([TickRecord(seq=i, t=i * 0.01, q_left=0.1 * i)])
            await asyncio.sleep(0.02)
            while not fast.queue.empty():
                got_fast.append(json.loads(fast.queue.get_nowait()))
        await stream.stop()
        got_slow = [json.loads(slow.queue.get_nowait()) for _ in range(slow.queue.qsize())]
        return got_fast, got_slow, slow.dropped

    fast, slow, dropped = asyncio.run(scenario())
    fast_seqs = [s for m in fast for s in m["columns"]["seq"]]
    assert fast_seqs == list(range(10))
    assert len(slow) == 3
    assert dropped == len(fast) - 3
    assert [m["msg_seq"] for m in slow] == [len(fast) - 2, len(fast) - 1, len(fast)]
    assert slow[-1]["columns"]["seq"][-1] == 9


def test_message_validates_against_its_schema_and_nan_is_null() -> None:
    async def scenario() -> str:
        stream = LiveStream(rate_hz=200.0)
        await stream.start()
        client = stream.connect()
        stream.push([TickRecord(seq=1, t=0.01), TickRecord(seq=2, t=0.02, q_left=0.5)])
        text = await asyncio.wait_for(client.queue.get(), 1.0)
        await stream.stop()
        return text

    msg = LiveTicks.model_validate_json(asyncio.run(scenario()))
    assert set(msg.columns) == set(STREAM_FIELDS)
    assert msg.columns["q_left"] == [None, 0.5]
    assert msg.columns["seq"] == [1, 2]


def test_nothing_is_kept_when_nobody_listens() -> None:
    stream = LiveStream()
    stream.push([TickRecord(seq=1, t=0.0)] * 100)
    assert len(stream._incoming) == 0
