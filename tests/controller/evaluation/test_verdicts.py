"""The interval over seeds and the verdict rule, on constructed numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.evaluation.verdicts import (
    Verdict,
    check_verdict,
    ordinal_verdict,
    t_interval,
    value_verdict,
)


def test_t_interval_of_five_values_by_hand() -> None:
    x = [8.0, 9.0, 10.0, 9.0, 9.0]
    iv = t_interval(x)
    sd = math.sqrt(sum((v - 9.0) ** 2 for v in x) / 4)  # 0.7071
    half = 2.7764451051977987 * sd / math.sqrt(5)  # t(0.975, 4) from tables: 2.776
    assert (iv.n, iv.mean, iv.sd) == (5, 9.0, pytest.approx(sd))
    assert (iv.low, iv.high) == (pytest.approx(9.0 - half), pytest.approx(9.0 + half))
    assert iv.text(".2f") == "9.00 [8.12, 9.88]"


def test_degenerate_intervals() -> None:
    same = t_interval([10.0, 10.0, 10.0])
    assert (same.low, same.high) == (10.0, 10.0)
    one = t_interval([3.0, math.nan])
    assert one.n == 1 and one.low == one.high == 3.0 and math.isnan(one.sd)
    assert t_interval([]).n == 0 and math.isnan(t_interval([]).mean)


def test_value_verdict() -> None:
    iv = t_interval([8.0, 9.0, 10.0, 9.0, 9.0])  # [8.12, 9.88]
    assert value_verdict(9.375, iv) is Verdict.REPRODUCED
    assert value_verdict(10.0, iv) is Verdict.DIFFERS
    assert value_verdict(8.0, iv) is Verdict.DIFFERS
    # Every seed 10 of 10: only 10 is inside.
    assert value_verdict(10.0, t_interval([10.0] * 5)) is Verdict.REPRODUCED
    assert value_verdict(9.625, t_interval([10.0] * 5)) is Verdict.DIFFERS
    assert value_verdict(1.0, t_interval([])) is Verdict.DIFFERS


def test_ordinal_verdict_needs_the_whole_interval_on_the_claimed_side() -> None:
    assert ordinal_verdict(t_interval([1.8, 2.0, 2.2]), 1) is Verdict.REPRODUCED  # [1.50, 2.50]
    straddles = t_interval([-1.0, 2.0, 3.0])  # mean 1.33, interval reaches below 0
    assert straddles.low < 0 < straddles.mean
    assert ordinal_verdict(straddles, 1) is Verdict.DIFFERS
    assert ordinal_verdict(t_interval([0.8, 0.85, 0.9]), -1, threshold=1.0) is Verdict.REPRODUCED
    assert ordinal_verdict(t_interval([0.8, 0.85, 0.9]), 1, threshold=0.5) is Verdict.REPRODUCED
    assert ordinal_verdict(t_interval([0.8, 0.85, 0.9]), 1, threshold=0.85) is Verdict.DIFFERS
    with pytest.raises(ValueError, match="direction"):
        ordinal_verdict(t_interval([1.0, 2.0]), 0)


def test_check_verdict() -> None:
    assert check_verdict(0.27707, 0.2771, 5e-5) is Verdict.REPRODUCED
    assert check_verdict(0.2772, 0.2771, 5e-5) is Verdict.DIFFERS
    assert check_verdict(math.nan, 0.0, 1.0) is Verdict.DIFFERS


@given(st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=30))
@settings(max_examples=60, deadline=None)
def test_interval_contains_the_mean_and_shrinks_to_it(x: list[float]) -> None:
    iv = t_interval(x)
    assert iv.low <= iv.mean + 1e-9 and iv.mean <= iv.high + 1e-9
    assert iv.mean == pytest.approx(float(np.mean(x)), abs=1e-9)
    assert value_verdict(iv.mean, iv) is Verdict.REPRODUCED
