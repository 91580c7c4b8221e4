"""Decimated lines show what the whole line shows: per pixel column the same lowest and
highest value (every peak kept), the same breaks, the same steps and spans."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from controller.evaluation.decimation import (
    column_extremes,
    columns_of,
    step_changes,
    true_runs,
)

_VALUES = st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.just(np.nan),
                    st.sampled_from([0.0, 1.0]))


@st.composite
def lines(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, int]:
    n = draw(st.integers(0, 400))
    steps = draw(arrays(np.float64, n, elements=st.sampled_from([0.0, 0.01, 0.1, 1.0])))
    x = np.cumsum(steps)
    y = draw(arrays(np.float64, n, elements=_VALUES))
    return x, y, draw(st.integers(1, 60))


def _extremes(x: np.ndarray, y: np.ndarray, columns: int, lo: float, hi: float
              ) -> dict[tuple[int, int], tuple[float, float, int, int]]:
    """Per (unbroken stretch, column): min, max, first and last index (reference)."""
    col = columns_of(x, columns, lo, hi)
    out: dict[tuple[int, int], list[float]] = defaultdict(list)
    first: dict[tuple[int, int], int] = {}
    last: dict[tuple[int, int], int] = {}
    stretch = 0
    for i, (c, v) in enumerate(zip(col, y, strict=True)):
        if not np.isfinite(v):
            if i > 0 and np.isfinite(y[i - 1]):
                stretch += 1
            continue
        key = (stretch, int(c))
        out[key].append(float(v))
        first.setdefault(key, i)
        last[key] = i
    return {k: (min(v), max(v), first[k], last[k]) for k, v in out.items()}


@settings(max_examples=200, deadline=None)
@given(lines())
def test_every_column_keeps_its_lowest_and_highest_value(
        line: tuple[np.ndarray, np.ndarray, int]) -> None:
    x, y, columns = line
    keep = column_extremes(x, y, columns)
    assert np.all(np.diff(keep) > 0)
    lo, hi = (float(x[0]), float(x[-1])) if x.size else (0.0, 1.0)
    whole = _extremes(x, y, columns, lo, hi)
    kept = _extremes(x[keep], y[keep], columns, lo, hi)
    # Same stretches in the same columns, with the same lowest and highest values ...
    assert {k: v[:2] for k, v in kept.items()} == {k: v[:2] for k, v in whole.items()}
    # ... entered and left at the same samples.
    assert {k: (int(keep[v[2]]), int(keep[v[3]])) for k, v in kept.items()} == {
        k: v[2:] for k, v in whole.items()}
    # Breaks stay where they were: between two kept samples a break was kept if and
    # only if the whole line had one there.
    for a, b in zip(keep[:-1], keep[1:], strict=True):
        broken = not np.isfinite(y[a:b + 1]).all()
        assert broken == (not np.isfinite(y[a]) or not np.isfinite(y[b]))


def test_a_long_line_falls_to_four_samples_a_column_and_keeps_its_spikes() -> None:
    rng = np.random.default_rng(3)
    x = np.arange(20_000) * 0.01
    y = np.asarray(rng.normal(size=x.size), dtype=np.float64)
    y[12_345] = 40.0  # one tick's spike
    y[5_000:5_100] = np.nan
    keep = column_extremes(x, y, 800)
    assert keep.size <= 4 * 800 + 1
    assert 12_345 in keep and float(np.nanmax(y[keep])) == 40.0
    assert int(np.isnan(y[keep]).sum()) == 1  # one break for the gap


def test_bad_lines_are_refused() -> None:
    with pytest.raises(ValueError, match="non-decreasing"):
        column_extremes(np.array([0.0, 2.0, 1.0]), np.zeros(3), 10)
    with pytest.raises(ValueError, match="one length"):
        column_extremes(np.zeros(3), np.zeros(2), 10)
    with pytest.raises(ValueError, match="at least 1"):
        columns_of(np.zeros(3), 0, 0.0, 1.0)


@given(arrays(np.float64, st.integers(0, 200), elements=st.sampled_from([0.0, 1.0, 2.0])))
def test_a_step_line_keeps_every_change(y: np.ndarray) -> None:
    keep = step_changes(y)
    if y.size == 0:
        assert keep.size == 0
        return
    # Re-expanding the kept steps (each value held until the next kept sample) gives
    # the whole line back.
    held = np.repeat(y[keep], np.diff(np.append(keep, y.size)))
    assert np.array_equal(held, y)
    assert keep[0] == 0 and keep[-1] == y.size - 1


@given(arrays(np.bool_, st.integers(0, 200)))
def test_true_runs_cover_exactly_the_true_samples(mask: np.ndarray) -> None:
    runs = true_runs(mask)
    back = np.zeros(mask.size, dtype=bool)
    for a, b in runs:
        assert a <= b and mask[a] and mask[b]
        back[a:b + 1] = True
    assert np.array_equal(back, mask)
    assert all(b + 1 < c for (_a, b), (c, _d) in zip(runs[:-1], runs[1:], strict=True))
