"""Timing checks over the finite timestamps when some are not (regression: one NaN stamp
switched every timing check off), the non-finite ones counted and said to be in no time
window, and a recording's span from its earliest to its latest stamp (regression: stamps
going backwards stored t_end < t_start)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from backend.emg import store
from backend.emg.quality_summary import TIMESTAMPS_NON_FINITE, QualitySummary
from controller.emg import quality


def test_one_nan_stamp_leaves_the_gap_checks_on() -> None:
    fs = 1000.0
    t = np.arange(3000) / fs
    t[1500:] += 0.5  # 500 samples missing
    t[10] = np.nan
    x = np.random.default_rng(1).normal(0, 1e-4, (t.size, 1))
    q = QualitySummary(fs, ["a"])
    q.add(t, x)
    q.finish()
    d = q.to_dict()
    assert d["gaps"] == 1 and d["dropped_samples"] == 500
    assert d["non_finite_timestamps"] == 1
    assert quality.DROPPED_SAMPLES in d["flags"] and TIMESTAMPS_NON_FINITE in d["flags"]
    assert "1 rows" in d["excluded_from_time_windows"]


def test_stamps_going_backwards_give_a_span_that_starts_first(tmp_path: Path) -> None:
    w = store.EmgWriter(tmp_path / "1.emgc", ["a"], 100.0)
    w.append(np.array([10.0, 9.0, np.nan, 5.0]), np.zeros((4, 1)))
    w.append(np.array([np.inf, 7.0]), np.zeros((2, 1)))
    w.close()
    assert (w.first_t, w.last_t) == (5.0, 10.0)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=1,
                max_size=40))
def test_the_span_is_the_finite_extremes(stamps: list[float]) -> None:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        w = store.EmgWriter(Path(d) / "1.emgc", ["a"], 100.0)
        w.append(np.array(stamps), np.zeros((len(stamps), 1)))
        w.abort()
    fin = [s for s in stamps if np.isfinite(s)]
    assert (w.first_t, w.last_t) == ((min(fin), max(fin)) if fin else (None, None))
