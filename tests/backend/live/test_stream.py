"""Fan-out to consoles: a message per arriving batch up to the rate cap, NaN as null, a slow
client only loses its own messages."""

from __future__ import annotations

import asyncio
import json

from backend.live.stream import LiveStream
from backend.schemas.live import STREAM_FIELDS, LiveTicks
from controller.tick_codec import pack
from controller.tick_record import TickRecord


def test_slow_client_drops_oldest_and_fast_client_gets_all() -> None:
    async def scenario() -> tuple[list[dict], list[dict], int]:
        stream = LiveStream(rate_hz=100.0, queue_size=3)
        await stream.start()
        slow = stream.connect()
        fast = stream.connect()
        got_fast: list[dict] = []
        for i in range(10):
            stream.push(pack([TickRecord(seq=i, t=i * 0.01, q_left=0.1 * i)]))
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
        stream.push(pack([TickRecord(seq=1, t=0.01), TickRecord(seq=2, t=0.02, q_left=0.5)]))
        text = await asyncio.wait_for(client.queue.get(), 1.0)
        await stream.stop()
        return text

    msg = LiveTicks.model_validate_json(asyncio.run(scenario()))
    assert set(msg.columns) == set(STREAM_FIELDS)
    assert msg.columns["q_left"] == [None, 0.5]
    assert msg.columns["seq"] == [1, 2]


def test_nothing_is_kept_when_nobody_listens() -> None:
    stream = LiveStream()
    stream.push(pack([TickRecord(seq=1, t=0.0)] * 100))
    assert len(stream._incoming) == 0


def _seqs(text: str) -> list[int]:
    return list(LiveTicks.model_validate_json(text).columns["seq"])


def test_each_batch_goes_out_as_it_arrives_and_faster_batches_are_merged() -> None:
    async def scenario() -> tuple[list[list[int]], list[list[int]]]:
        # Below the cap, every batch from the worker is its own message.
        fast = LiveStream(rate_hz=1000.0)
        await fast.start()
        client = fast.connect()
        alone = []
        for i in range(5):
            fast.push(pack([TickRecord(seq=i, t=i * 0.01)]))
            alone.append(_seqs(await asyncio.wait_for(client.queue.get(), 5.0)))
        await fast.stop()
        # Over the budget (here 2 messages/s after a burst of 2), batches arriving while
        # the sender waits for its next turn go out together in one message.
        slow = LiveStream(rate_hz=2.0)
        await slow.start()
        client = slow.connect()
        merged = []
        for i in range(2):
            slow.push(pack([TickRecord(seq=i, t=i * 0.01)]))
            merged.append(_seqs(await asyncio.wait_for(client.queue.get(), 5.0)))
        slow.push(pack([TickRecord(seq=2, t=0.02)]))
        await asyncio.sleep(0.05)  # the sender wakes and waits for its turn
        slow.push(pack([TickRecord(seq=3, t=0.03), TickRecord(seq=4, t=0.04)]))
        merged.append(_seqs(await asyncio.wait_for(client.queue.get(), 5.0)))
        await slow.stop()
        return alone, merged

    alone, merged = asyncio.run(scenario())
    assert alone == [[0], [1], [2], [3], [4]]
    assert merged == [[0], [1], [2, 3, 4]]


def test_one_encoding_for_all_clients_with_their_own_counters() -> None:
    async def scenario() -> list[dict]:
        stream = LiveStream(rate_hz=1000.0)
        await stream.start()
        first, second = stream.connect(), stream.connect()
        stream.push(pack([TickRecord(seq=7, t=0.07, t_host=1_700_000_000.5)]))
        texts = [await asyncio.wait_for(c.queue.get(), 5.0) for c in (first, second)]
        stream.push(pack([TickRecord(seq=8, t=0.08)]))
        await asyncio.wait_for(first.queue.get(), 5.0)
        await stream.stop()
        assert stream.messages == 2 and stream.sent == 4
        return [json.loads(t) for t in texts]

    a, b = asyncio.run(scenario())
    assert a["columns"] == b["columns"]
    assert a["columns"]["t_host"] == [1_700_000_000.5]
    assert a["msg_seq"] == b["msg_seq"] == 1
    assert a["sent_at"] == b["sent_at"]
