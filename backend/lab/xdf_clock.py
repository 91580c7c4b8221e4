"""Clock synchronisation of an XDF stream, in time linear in its offsets and samples.

LabRecorder stamps each stream in the clock of the computer that sent it and, every few
seconds, stores the offset between that clock and its own (a ClockOffset chunk: when it
was measured and the offset). A line fitted through the offsets maps each time stamp
onto the recording computer's clock: `t + intercept + slope * t`.

The offsets are split where the sending computer's clock was reset (a restart): where
the measurement time goes backwards, or where both the time between two measurements
and the change of offset are outliers (more than 5 median absolute deviations and 5 s,
and more than 10 deviations and 1 s). Each part gets its own line: a Huber fit (residuals
above 0.1 ms count linearly, so a measurement disturbed by network load does not pull
the line) by iteratively reweighted least squares, all parts at once with segment sums,
a fixed number of rounds. Each sample takes the line of its part, a part ending at the
first sample nearer the next part's first measurement than to its own last. A file with
many parts (20,000 random offsets, issue 28) therefore costs a few passes over its
offsets, not a fit per part.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: A reset: the time between measurements is more than this many median absolute
#: deviations and seconds from the median ...
RESET_TIME_MADS, RESET_TIME_S = 5.0, 5.0
#: ... and so is the change of offset.
RESET_OFFSET_MADS, RESET_OFFSET_S = 10.0, 1.0
#: Residual (s) beyond which an offset counts linearly rather than squared in the fit.
HUBER_S = 1e-4
#: Rounds of reweighting; a clean recording converges in two or three.
FIT_ROUNDS = 50
#: Smallest weight a measurement keeps (so no part's weights all vanish).
_MIN_WEIGHT = 1e-12


def _outliers(d: NDArray[np.float64], mads: float, seconds: float) -> NDArray[np.bool_]:
    dev = d - np.median(d)
    spread = np.median(np.abs(dev)) + np.finfo(float).eps
    return (np.abs(dev) / spread > mads) & (np.abs(dev) > seconds)


def parts(times: NDArray[np.float64], values: NDArray[np.float64]) -> NDArray[np.intp]:
    """First index of each part between clock resets (the first is 0)."""
    if times.size < 2:
        return np.zeros(min(times.size, 1), dtype=np.intp)
    dt, dv = np.diff(times), np.diff(values)
    resets = (dt < 0) | (_outliers(dt, RESET_TIME_MADS, RESET_TIME_S)
                         & _outliers(dv, RESET_OFFSET_MADS, RESET_OFFSET_S))
    return np.concatenate(([0], np.flatnonzero(resets) + 1)).astype(np.intp)


def fit(times: NDArray[np.float64], values: NDArray[np.float64],
        starts: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(intercepts, slopes) of the Huber line through each part's offsets. A part of
    one measurement, or whose measurements share one time, gets its (weighted) mean
    offset and no slope."""
    counts = np.diff(np.append(starts, times.size))
    part = np.repeat(np.arange(starts.size), counts)
    centre = np.add.reduceat(times, starts) / counts
    x = times - centre[part]
    w = np.ones_like(x)
    with np.errstate(all="ignore"):
        for _ in range(FIT_ROUNDS):
            sw = np.add.reduceat(w, starts)
            mx = np.add.reduceat(w * x, starts) / sw
            my = np.add.reduceat(w * values, starts) / sw
            dx = x - mx[part]
            sxx = np.add.reduceat(w * dx * dx, starts)
            sxy = np.add.reduceat(w * dx * (values - my[part]), starts)
            slope = np.where(sxx > 0, sxy / np.where(sxx > 0, sxx, 1.0), 0.0)
            intercept = my - slope * mx
            r = np.abs(values - intercept[part] - slope[part] * x)
            new = np.clip(HUBER_S / np.maximum(r, HUBER_S), _MIN_WEIGHT, 1.0)
            if np.array_equal(new, w):
                break
            w = new
        return intercept - slope * centre, slope


def _part_end(stamps: NDArray[np.float64], start: int, own_last: float,
              next_first: float) -> int:
    """First index from `start` of a sample nearer `next_first` than `own_last` (or the
    end), looking at a window that doubles, so the work is proportional to the samples
    the part takes."""
    size = 16
    at = start
    while at < stamps.size:
        window = stamps[at:at + size]
        nearer = np.abs(window - own_last) < np.abs(window - next_first)
        if not nearer.all():
            return at + int(np.argmin(nearer))
        at += window.size
        size *= 2
    return stamps.size


def synchronize(stamps: NDArray[np.float64], times: NDArray[np.float64],
                values: NDArray[np.float64]) -> NDArray[np.float64]:
    """`stamps` moved onto the recording computer's clock with the offsets (`times`,
    `values`) measured for the stream; unchanged without offsets. Non-finite results
    (offsets too large to add) are left for the caller to refuse."""
    out = stamps.copy()
    if stamps.size == 0 or times.size == 0:
        return out
    starts = parts(times, values)
    intercepts, slopes = fit(times, values, starts)
    ends = np.append(starts[1:], times.size) - 1
    begin = 0
    with np.errstate(all="ignore"):
        for k in range(starts.size):
            if k + 1 < starts.size:
                stop = _part_end(stamps, begin, float(times[ends[k]]),
                                 float(times[starts[k + 1]]))
            else:
                stop = stamps.size
            if stop > begin:
                out[begin:stop] += intercepts[k] + slopes[k] * stamps[begin:stop]
                begin = stop
            if begin == stamps.size:
                break
    return out
