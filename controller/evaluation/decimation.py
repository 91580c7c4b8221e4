"""Fewer points for the same picture: what a time-series figure needs of a long line.

A trial of 20,000 ticks drawn into an axes 800 pixels wide puts 25 samples into each
pixel column; drawing all of them costs time (and, for the SVG, bytes and one marker
element per sample) while the picture only shows, per column, where the line enters and
leaves it and how low and high it goes. `column_extremes` keeps exactly those samples
(first, last, lowest and highest of each column; the M4 rule of Jugel et al., VLDB
2014), so every peak stays. `step_changes` keeps the samples of a step line where its
value changes, and `true_runs` turns a boolean strip into spans, both lossless.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IndexArray = NDArray[np.intp]


def columns_of(x: FloatArray, columns: int, lo: float, hi: float) -> IndexArray:
    """The column (0..columns-1) of each `x` when `lo..hi` is cut into `columns` equal
    columns; values outside the range fall into the first or last column."""
    if columns < 1:
        raise ValueError(f"columns must be at least 1, got {columns}")
    span = hi - lo
    if not (np.isfinite(span) and span > 0):
        return np.zeros(x.shape, dtype=np.intp)
    col = np.floor((np.asarray(x, dtype=np.float64) - lo) * (columns / span))
    return np.clip(col, 0, columns - 1).astype(np.intp)


def column_extremes(x: FloatArray, y: FloatArray, columns: int,
                    lo: float | None = None, hi: float | None = None) -> IndexArray:
    """Indices (ascending) of the samples of the line `(x, y)` worth drawing into
    `columns` pixel columns spanning `lo..hi` (default: the range of `x`).

    `x` must be finite and non-decreasing (time). A non-finite `y` breaks the line;
    of consecutive breaks the first is kept, so the line breaks where it did. Within
    each column, each unbroken stretch keeps its first and last sample and the first
    of its lowest and of its highest: the decimated line enters, leaves, spans and
    joins every column as the whole line did.
    """
    xs = np.asarray(x, dtype=np.float64)
    ys = np.asarray(y, dtype=np.float64)
    if xs.shape != ys.shape or xs.ndim != 1:
        raise ValueError(f"x and y must be 1-D of one length, got {xs.shape} and {ys.shape}")
    n = xs.size
    if n == 0:
        return np.zeros(0, dtype=np.intp)
    if not np.isfinite(xs).all() or (n > 1 and bool(np.any(np.diff(xs) < 0))):
        raise ValueError("x must be finite and non-decreasing")
    col = columns_of(xs, columns, float(xs[0]) if lo is None else lo,
                     float(xs[-1]) if hi is None else hi)
    finite = np.isfinite(ys)
    starts_mask = np.ones(n, dtype=bool)
    # A new run where finiteness changes, or where a finite stretch enters a new
    # column (a run of breaks stays one run across columns).
    starts_mask[1:] = ((col[1:] != col[:-1]) & finite[1:]) | (finite[1:] != finite[:-1])
    starts = np.flatnonzero(starts_mask)
    ends = np.append(starts[1:], n) - 1
    run_finite = finite[starts]
    # A run is all finite or all breaks; breaks are +inf for the minimum and -inf for
    # the maximum, so they never win, and only their first sample is kept below.
    low = np.where(finite, ys, np.inf)
    high = np.where(finite, ys, -np.inf)
    run_of = np.repeat(np.arange(starts.size), ends - starts + 1)
    keep = [starts, ends[run_finite]]
    for values, reduce in ((low, np.minimum), (high, np.maximum)):
        extreme = reduce.reduceat(values, starts)
        hits = np.flatnonzero((values == extreme[run_of]) & finite)
        first = np.ones(hits.size, dtype=bool)
        first[1:] = run_of[hits[1:]] != run_of[hits[:-1]]
        keep.append(hits[first])
    return np.unique(np.concatenate(keep))


def step_changes(y: NDArray[np.float64]) -> IndexArray:
    """Indices of a step line (`drawstyle="steps-post"`) that draw the same steps:
    the first sample, every sample whose value differs from the one before, and the
    last sample (which ends the final step)."""
    ys = np.asarray(y, dtype=np.float64)
    n = ys.size
    if n == 0:
        return np.zeros(0, dtype=np.intp)
    same = (ys[1:] == ys[:-1]) | (np.isnan(ys[1:]) & np.isnan(ys[:-1]))
    keep = np.ones(n, dtype=bool)
    keep[1:] = ~same
    keep[-1] = True
    return np.flatnonzero(keep)


def true_runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """The runs of True in `mask` as `(first, last)` index pairs (last included)."""
    m = np.asarray(mask, dtype=bool)
    if m.size == 0:
        return []
    edges = np.diff(np.concatenate(([False], m, [False])).astype(np.int8))
    firsts = np.flatnonzero(edges == 1)
    lasts = np.flatnonzero(edges == -1) - 1
    return [(int(a), int(b)) for a, b in zip(firsts, lasts, strict=True)]
