"""Quality flags from the device clock, against a plain loop over the steps."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from backend.live.trial_quality import GAP_FACTOR, assess, describe

PERIOD = 0.01


def _oracle(t: list[float]) -> dict[str, float | int]:
    gaps, missing, largest, back, backstep = 0, 0.0, 0.0, 0, 0.0
    for a, b in zip(t, t[1:], strict=False):
        step = b - a
        if step > GAP_FACTOR * PERIOD:
            gaps, missing, largest = gaps + 1, missing + step - PERIOD, max(largest, step)
        elif step <= 0:
            back, backstep = back + 1, max(backstep, -step)
    out: dict[str, float | int] = {}
    if gaps:
        out.update(time_gaps=gaps, missing_s=missing, largest_gap_s=largest)
    if back:
        out.update(time_backwards=back, largest_backstep_s=backstep)
    return out


# A device clock: mostly one period per step, sometimes skipped samples, sometimes a
# restart at a smaller time.
steps = st.lists(st.one_of(st.just(1), st.integers(2, 500), st.integers(-900, 0)),
                 min_size=0, max_size=300)


@given(steps)
def test_flags_match_a_plain_loop(k: list[int]) -> None:
    t = [round(x * PERIOD, 6) for x in np.cumsum([0, *k])]
    got = assess(np.asarray(t))
    want = _oracle(t)
    assert got.keys() == want.keys()
    for key, value in want.items():
        assert got[key] == (value if isinstance(value, int) else round(value, 6)) or \
            abs(got[key] - value) < 1e-6


def test_the_issue_case_a_device_restart_and_a_hole() -> None:
    # 4.27 s of samples, the device restarts (0.24 s), then an 8.8 s hole.
    t = np.concatenate([np.arange(0, 428) * PERIOD, 0.24 + np.arange(0, 100) * PERIOD,
                        1.23 + 8.8 + np.arange(0, 100) * PERIOD])
    flags = assess(t)
    assert flags["time_backwards"] == 1
    assert abs(flags["largest_backstep_s"] - (4.27 - 0.24)) < 1e-9
    assert flags["time_gaps"] == 1 and abs(flags["largest_gap_s"] - 8.8) < 1e-9
    assert abs(flags["missing_s"] - 8.79) < 1e-6
    assert "backwards" in describe(flags) and "gap" in describe(flags)
    assert assess(np.arange(1000) * PERIOD) == {} and describe({}) == ""
