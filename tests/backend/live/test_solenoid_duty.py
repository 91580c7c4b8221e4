"""The solenoids' duty-cycle budget (backend/live/solenoid_duty.py): the issue's ten
300 ms pulses in 3.9 s, the wait each refusal names, and any schedule's duty."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from backend.live.solenoid_duty import MAX_DUTY, MAX_ON_S, SolenoidDuty


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_ten_300_ms_pulses_in_3_9_s_get_three_through_with_the_wait_named() -> None:
    clock = Clock()
    duty = SolenoidDuty(clock)
    passed, refusals = [], []
    for k in range(10):
        clock.t = 100.0 + 0.39 * k
        why = duty.refusal("left")
        if why:
            refusals.append((k, why))
            continue
        passed.append(k)
        clock.t += 0.3  # the pulse
        duty.record("left", 0.3)
    assert passed == [0, 4, 8]  # 0.9 s on in 3.9 s: 23 %, not 76 %
    k, first = refusals[0]
    assert k == 1
    # Released at 100.3, off for 3 x 0.3 s: allowed from 101.2, asked at 100.39.
    assert "left solenoid is cooling down" in first and "in 0.8 s" in first
    assert "25 %" in first
    assert duty.refusal("right") == ""  # the other coil has its own budget


def test_wait_counts_down_to_zero_and_caps_one_energisation() -> None:
    clock = Clock()
    duty = SolenoidDuty(clock)
    duty.record("right", 0.2)
    assert duty.wait_s("right") == pytest.approx(0.6)
    clock.t += 0.6
    assert duty.wait_s("right") == 0.0
    duty.record("right", 5.0)  # more than any step may energise: counted as the cap
    assert duty.wait_s("right") == pytest.approx(3 * MAX_ON_S)
    duty.record("left", 0.0)  # nothing energised: no cool-down
    assert duty.wait_s("left") == 0.0
    with pytest.raises(ValueError, match="side"):
        duty.wait_s("middle")


@given(st.lists(st.tuples(st.floats(0.0, 2.0), st.floats(0.01, 0.3)), min_size=1,
                max_size=30))
def test_no_schedule_exceeds_the_duty_over_its_cycles(asks: list[tuple[float, float]]) -> None:
    """Whatever the experimenter asks for, the coil's on time from its first pulse to
    the end of the last cool-down is at most MAX_DUTY of that span."""
    clock = Clock()
    duty = SolenoidDuty(clock)
    start, on = None, 0.0
    for gap, length in asks:
        clock.t += gap
        if duty.refusal("left"):
            continue
        start = clock.t if start is None else start
        clock.t += length
        duty.record("left", length)
        on += length
    if start is not None:
        end = clock.t + duty.wait_s("left")
        assert on <= MAX_DUTY * (end - start) + 1e-9
