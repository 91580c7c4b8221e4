"""The control loop with an in-memory device: commands, faults, gaps, timing."""

from __future__ import annotations

from collections import deque

import pytest

from controller.controllers.passthrough import PassThroughController
from controller.device.base import Device, LockCommand, Sample
from controller.interface import Controller
from controller.runner.loop import ControlLoop, LoopTiming
from controller.tick_record import TickFlag, TickRecord


class ListDevice(Device):
    """Hands out prepared samples and keeps every command."""

    kind = "list"

    def __init__(self, samples: list[Sample]) -> None:
        self.samples = deque(samples)
        self.sent: list[LockCommand] = []
        self.released = 0

    def open(self) -> None:
        pass

    def read(self, timeout: float) -> Sample | None:
        return self.samples.popleft() if self.samples else None

    def send(self, command: LockCommand) -> None:
        self.sent.append(command)

    def release(self) -> None:
        self.released += 1

    def close(self) -> None:
        self.release()


class LockEverything(Controller):
    name = "lock-all"

    def step(self, sample: Sample) -> TickRecord:
        return TickRecord(seq=sample.seq, t=sample.t, lock_left=True, lock_right=True)

    def reset(self) -> None:
        pass


class Exploding(Controller):
    name = "explodes"

    def step(self, sample: Sample) -> TickRecord:
        raise RuntimeError("boom")

    def reset(self) -> None:
        pass


def samples(seqs: list[int]) -> list[Sample]:
    return [Sample(seq=s, t=s * 0.01, counts=(3100, 3100, 12900, 12900)) for s in seqs]


def test_commands_follow_the_controller() -> None:
    dev = ListDevice(samples([0, 1, 2]))
    loop = ControlLoop(dev, LockEverything())
    recs = [loop.tick() for _ in range(3)]
    assert all(r is not None and r.lock_left for r in recs)
    assert [(c.lock_left, c.lock_right) for c in dev.sent] == [(True, True)] * 3
    assert [c.seq for c in dev.sent] == [1, 2, 3]


def test_a_raising_controller_yields_a_flagged_no_lock_tick() -> None:
    dev = ListDevice(samples([7]))
    rec = ControlLoop(dev, Exploding()).tick()
    assert rec is not None
    assert rec.flags & TickFlag.CONTROLLER_ERROR
    assert rec.seq == 7
    assert (dev.sent[0].lock_left, dev.sent[0].lock_right) == (False, False)


def test_sequence_gaps_are_flagged_and_counted() -> None:
    dev = ListDevice(samples([0, 1, 5, 6]))
    loop = ControlLoop(dev, PassThroughController())
    flags = [loop.tick().flags for _ in range(4)]  # type: ignore[union-attr]
    assert [bool(f & TickFlag.GAP) for f in flags] == [False, False, True, False]
    assert loop.timing.gaps == 1


def test_timeout_returns_none_and_counts() -> None:
    loop = ControlLoop(ListDevice([]), PassThroughController())
    assert loop.tick() is None
    assert loop.timing.timeouts == 1


def test_overrun_is_a_tick_longer_than_the_period() -> None:
    clock = iter([0.0, 0.002, 0.010, 0.025])  # second tick takes 15 ms
    dev = ListDevice(samples([0, 1]))
    loop = ControlLoop(dev, PassThroughController(), clock=lambda: next(clock))
    first, second = loop.tick(), loop.tick()
    assert first is not None and not first.flags & TickFlag.OVERRUN
    assert second is not None and second.flags & TickFlag.OVERRUN
    assert loop.timing.overruns == 1


def test_timing_summary_on_a_known_schedule() -> None:
    timing = LoopTiming(period_s=0.01)
    starts = [0.0, 0.010, 0.021, 0.030, 0.040]
    for s in starts:
        timing.record(s, s + 0.001)
    summary = timing.summary()
    assert summary.ticks == 5
    assert summary.period_mean_ms == pytest.approx(10.0)
    assert summary.jitter_max_ms == pytest.approx(1.0)
    assert summary.compute_p50_us == pytest.approx(1000.0)
    assert summary.overruns == 0
