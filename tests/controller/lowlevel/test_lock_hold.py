"""Tests of the 0.3 s lock hold."""

from __future__ import annotations

import pytest

from controller.lowlevel.lock_hold import LockHold


def _run(hold: LockHold, requests: list[tuple[bool, bool]]) -> list[tuple[bool, bool]]:
    return [hold.update(left, right) for left, right in requests]


def test_single_request_holds_exactly_30_ticks() -> None:
    hold = LockHold(0.3, 0.01)
    assert hold.hold_ticks == 30
    out = _run(hold, [(True, False)] + [(False, False)] * 40)
    on = [i for i, (left, _) in enumerate(out) if left]
    assert on == list(range(30))
    assert not any(right for _, right in out)


def test_hold_counts_from_the_last_request_per_side() -> None:
    hold = LockHold()
    req = [(False, False)] * 60
    req[0] = (True, True)
    req[10] = (True, False)  # left renewed at tick 10, right not
    out = _run(hold, req)
    left_on = [i for i, (left, _) in enumerate(out) if left]
    right_on = [i for i, (_, right) in enumerate(out) if right]
    assert left_on == list(range(40))
    assert right_on == list(range(30))


def test_continuous_request_then_release() -> None:
    hold = LockHold(hold_s=0.05, dt=0.01)
    out = _run(hold, [(True, True)] * 7 + [(False, False)] * 8)
    # Last request at tick 6: on through tick 6 + 5 - 1 = 10.
    assert [left for left, _ in out] == [True] * 11 + [False] * 4


def test_reset_and_validation() -> None:
    hold = LockHold()
    hold.update(True, True)
    assert hold.remaining == (29, 29)
    hold.reset()
    assert hold.update(False, False) == (False, False)
    with pytest.raises(ValueError):
        LockHold(hold_s=0.0)
    with pytest.raises(ValueError):
        LockHold(dt=-0.01)
