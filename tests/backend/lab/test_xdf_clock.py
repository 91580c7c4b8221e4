"""Clock synchronisation of XDF streams: offsets on a line are applied exactly, a
disturbed offset does not pull the line, a clock reset splits the offsets, and the
all-parts-at-once fit and windowed part search give what a fit per part and a scan per
sample give (issue 28: 20,000 random offsets took 465 s as a fit per part)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from backend.lab import xdf_clock


@settings(max_examples=50, deadline=None, derandomize=True, database=None)
@given(st.floats(-1e3, 1e3), st.floats(-1e-4, 1e-4), st.integers(2, 60),
       st.floats(0.0, 1e6))
def test_offsets_on_a_line_map_every_stamp_onto_it(intercept: float, slope: float,
                                                   count: int, t0: float) -> None:
    times = (t0 + 5.0 * np.arange(count)).astype(np.float64)
    values = (intercept + slope * times).astype(np.float64)
    stamps = np.linspace(t0, times[-1], 200)
    got = xdf_clock.synchronize(stamps, times, values)
    np.testing.assert_allclose(got, stamps + intercept + slope * stamps, rtol=0, atol=1e-7)


def test_a_disturbed_offset_does_not_pull_the_line() -> None:
    rng = np.random.default_rng(2)
    times = (100.0 + 5.0 * np.arange(50)).astype(np.float64)
    values = (0.25 + rng.uniform(-1e-5, 1e-5, 50)).astype(np.float64)
    values[20] += 0.5  # one measurement during a network stall
    got = xdf_clock.synchronize(np.array([150.0, 300.0]), times, values)
    # A least-squares line would move by 0.5/50 = 10 ms; the Huber line stays put.
    np.testing.assert_allclose(got - [150.0, 300.0], 0.25, atol=2e-5)


def test_a_clock_reset_gives_each_part_its_own_offset() -> None:
    # The sending computer restarted: its measurements jump by 1000 s, the offset by 7 s.
    times = np.concatenate((100.0 + 5.0 * np.arange(10), 1200.0 + 5.0 * np.arange(10)))
    values = np.concatenate((np.full(10, 0.5), np.full(10, 7.5)))
    assert xdf_clock.parts(times, values).tolist() == [0, 10]
    stamps = np.array([100.0, 140.0, 600.0, 700.0, 1200.0, 1240.0])
    got = xdf_clock.synchronize(stamps, times, values)
    # A sample belongs to its part up to the first one nearer the next part's start
    # (the midpoint of 145 and 1200).
    np.testing.assert_allclose(got - stamps, [0.5, 0.5, 0.5, 7.5, 7.5, 7.5], atol=1e-9)


def _reference(stamps: np.ndarray, times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """A fit per part and a scan per sample: the slow way, written out."""
    out = stamps.copy()
    starts = xdf_clock.parts(times, values).tolist()
    ends = [*starts[1:], times.size]
    begin = 0
    for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
        i, s = xdf_clock.fit(times[a:b], values[a:b], np.array([0]))
        stop = stamps.size
        if k + 1 < len(starts):
            own, nxt = times[b - 1], times[b]
            stop = begin
            while stop < stamps.size and abs(stamps[stop] - own) < abs(stamps[stop] - nxt):
                stop += 1
        out[begin:stop] += i[0] + s[0] * stamps[begin:stop]
        begin = max(begin, stop)
    return out


_times = arrays(np.float64, st.integers(1, 60), elements=st.floats(0.0, 1000.0))


@settings(max_examples=100, deadline=None, derandomize=True, database=None)
@given(_times, st.data(), arrays(np.float64, st.integers(0, 80),
                                 elements=st.floats(0.0, 1000.0)))
def test_random_offsets_give_what_a_fit_per_part_gives(times: np.ndarray, data: st.DataObject,
                                                       stamps: np.ndarray) -> None:
    values = data.draw(arrays(np.float64, times.size, elements=st.floats(-100.0, 100.0)))
    np.testing.assert_allclose(xdf_clock.synchronize(stamps, times, values),
                               _reference(stamps, times, values), rtol=1e-9, atol=1e-9)


def test_thousands_of_random_offsets() -> None:
    # Issue 28's 20,000 random offsets split into about 10,000 parts; each costs a slice
    # of the passes over all offsets, not a fit of its own.
    rng = np.random.default_rng(4)
    stamps = 100.0 + np.arange(50) / 100
    for count in (2_000, 20_000):
        times, values = rng.uniform(0, 1000, count), rng.uniform(-100, 100, count)
        assert xdf_clock.parts(times, values).size > count // 4
        got = xdf_clock.synchronize(stamps, times, values)
        assert np.isfinite(got).all()
        if count == 2_000:
            np.testing.assert_allclose(got, _reference(stamps, times, values), rtol=0,
                                       atol=1e-9)
