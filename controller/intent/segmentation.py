"""Segmentation of a continuous hip-flexion recording into lifts (demonstrations).

The paper segmented its demonstrations by hand; this proposes segments that the
experimenter then edits, so it returns plain sample indices.

Method, on `m = (theta_L + theta_R) / 2`, the mean flexion of both hips:

1. Smooth each hip with a Savitzky-Golay filter (position and velocity), which keeps
   the onset sharp while removing encoder noise.
2. Rest baseline per hip: samples where both hips have been still for a while
   (`quiet_min_s`) at a low posture; the baseline is interpolated between them, so a
   slow offset drift of the encoders does not shift the thresholds.
3. Candidate lifts: stretches where `m` exceeds the baseline by `detect_rad`. Walking
   moves the hips in anti-phase, so `m` hardly changes; a lift flexes both hips.
   At the peak both hips must also be flexed by `min_each_hip_rad` (rejects stair
   steps, where only the leading hip flexes much).
4. Onset: going back from the threshold crossing, the last sample where the wearer is
   at rest again: `m` within `rest_tol_rad` of the baseline and not flexing faster
   than `rest_velocity`. End: the same going forward, with extension velocity.
5. Overlapping candidates are merged; too short or too long ones dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controller.device.base import SAMPLE_PERIOD_S

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class SegmentedLift:
    """One lift as sample indices into the recording: onset, peak flexion, return to rest.

    `start <= peak <= end`; the demonstration is `q[start:end + 1]`.
    """

    start: int
    peak: int
    end: int

    def __post_init__(self) -> None:
        if not 0 <= self.start <= self.peak <= self.end:
            raise ValueError(f"need 0 <= start <= peak <= end, got {self}")

    def as_slice(self) -> slice:
        """The demonstration's samples, `q[seg.as_slice()]` (end included)."""
        return slice(self.start, self.end + 1)


@dataclass(frozen=True, slots=True)
class SegmentationParams:
    """Thresholds of the segmentation. Angles in rad, velocities in rad/s, times in s.

    Attributes:
        smooth_window_s: Savitzky-Golay window (0.11 s = 11 samples at 100 Hz).
        smooth_order: Savitzky-Golay polynomial order.
        detect_rad: mean flexion above rest that makes a candidate lift (0.6 rad, 34
            deg; lifts reach 60-110 deg, walking keeps the mean within ~10 deg).
        min_each_hip_rad: flexion of each hip above its rest at the peak (0.35 rad,
            20 deg; a stair step flexes one hip only).
        rest_tol_rad: mean flexion above rest still counted as rest at onset and end
            (5 deg; covers sway and a little drift between quiet spells).
        rest_velocity: mean flexion speed below which the wearer is not moving into or
            out of the lift (0.02 rad/s, about 3 SD of the smoothed velocity noise at
            0.06 deg encoder noise). Low, because the walk from the threshold
            crossing stops at the first slow sample: sway can only end it early.
        quiet_velocity: per-hip speed below which a sample can serve as rest baseline.
        quiet_min_s: minimum duration of a quiet spell used as baseline (excludes the
            brief turnarounds of walking, where both hips stop together).
        quiet_level_rad: quiet spells must lie within this of the recording's low
            posture (5th percentile), so a held bent posture is not taken as rest.
        max_search_s: how far onset and end are searched from the threshold crossing.
        min_duration_s: shorter candidates are dropped.
        max_duration_s: longer candidates are dropped (not a lift).
    """

    smooth_window_s: float = 0.11
    smooth_order: int = 2
    detect_rad: float = 0.6
    min_each_hip_rad: float = 0.35
    rest_tol_rad: float = 0.087
    rest_velocity: float = 0.02
    quiet_velocity: float = 0.1
    quiet_min_s: float = 0.3
    quiet_level_rad: float = 0.26
    max_search_s: float = 3.0
    min_duration_s: float = 0.5
    max_duration_s: float = 15.0

    def __post_init__(self) -> None:
        positive = (
            "smooth_window_s", "detect_rad", "min_each_hip_rad", "rest_tol_rad",
            "rest_velocity", "quiet_velocity", "quiet_min_s", "quiet_level_rad",
            "max_search_s", "min_duration_s", "max_duration_s",
        )
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")
        if self.rest_tol_rad >= self.detect_rad:
            raise ValueError("rest_tol_rad must be below detect_rad")
        if self.min_duration_s >= self.max_duration_s:
            raise ValueError("min_duration_s must be below max_duration_s")
        if self.smooth_order < 1:
            raise ValueError("smooth_order must be at least 1")


def bridge_gaps(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles (N x 2) with bad samples (NaN) bridged linearly, so segmentation sees a
    continuous signal. A column with no valid sample raises ValueError."""
    out = q.copy()
    idx = np.arange(q.shape[0])
    for j in range(q.shape[1]):
        ok = ~np.isnan(q[:, j])
        if not ok.any():
            raise ValueError(f"column {j} has no valid sample")
        out[:, j] = np.interp(idx, idx[ok], q[ok, j])
    return out


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Inclusive `(first, last)` index pairs of the True stretches of `mask`."""
    padded = np.concatenate(([False], mask, [False]))
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _baseline(
    qs: FloatArray, vs: FloatArray, fs: float, p: SegmentationParams
) -> FloatArray:
    """Per-hip rest level at every sample, `(K, 2)`."""
    k_len = qs.shape[0]
    m = qs.mean(axis=1)
    low = float(np.percentile(m, 5))
    quiet = (np.abs(vs) < p.quiet_velocity).all(axis=1) & (m < low + p.quiet_level_rad)
    min_len = max(round(p.quiet_min_s * fs), 1)
    idx = [np.arange(a, b + 1) for a, b in _runs(quiet) if b - a + 1 >= min_len]
    base = np.empty_like(qs)
    if not idx:
        base[:] = np.percentile(qs, 5, axis=0)
        return base
    keep = np.concatenate(idx)
    k = np.arange(k_len)
    for h in range(2):
        base[:, h] = np.interp(k, keep, qs[keep, h])
    return base


def segment_lifts(
    t: FloatArray, q: FloatArray, params: SegmentationParams | None = None
) -> list[SegmentedLift]:
    """Find the lifts in a recording.

    Args:
        t: `(K,)` strictly increasing sample times (s), nominally 100 Hz.
        q: `(K, 2)` hip flexion (rad), left and right.
        params: thresholds; defaults documented in `SegmentationParams`.

    Returns:
        Lifts in time order, non-overlapping; a lift cut by the first or last sample of
        the recording (not at rest there) is left out.

    Raises:
        ValueError: bad shapes, NaN, non-increasing time, or a recording shorter than
            the smoothing window.
    """
    p = params or SegmentationParams()
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if t.ndim != 1 or q.shape != (t.shape[0], 2):
        raise ValueError(f"need t (K,) and q (K, 2), got {t.shape} and {q.shape}")
    if not (np.isfinite(t).all() and np.isfinite(q).all()):
        raise ValueError("recording contains NaN or inf")
    if t.shape[0] >= 2 and not (np.diff(t) > 0).all():
        raise ValueError("sample times must be strictly increasing")
    k_len = t.shape[0]
    dt = float(np.median(np.diff(t))) if k_len >= 2 else SAMPLE_PERIOD_S
    fs = 1.0 / dt
    win = max(round(p.smooth_window_s * fs) | 1, (p.smooth_order + 2) | 1)
    if k_len < win:
        raise ValueError(f"recording of {k_len} samples is shorter than the smoothing window")
    # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
    from scipy.signal import savgol_filter

    qs = savgol_filter(q, win, p.smooth_order, axis=0, mode="interp")
    vs = savgol_filter(q, win, p.smooth_order, deriv=1, delta=dt, axis=0, mode="interp")
    base = _baseline(qs, vs, fs, p)
    rel = qs - base
    d = rel.mean(axis=1)
    v = vs.mean(axis=1)
    search = round(p.max_search_s * fs)

    def at_rest_before(k: int) -> bool:
        return bool(d[k] <= p.rest_tol_rad and v[k] <= p.rest_velocity)

    def at_rest_after(k: int) -> bool:
        return bool(d[k] <= p.rest_tol_rad and v[k] >= -p.rest_velocity)

    candidates: list[list[int]] = []
    for a, b in _runs(d > p.detect_rad):
        peak = a + int(np.argmax(d[a : b + 1]))
        lo = max(a - search, 0)
        k = a
        while k > lo and not at_rest_before(k):
            k -= 1
        start = k if at_rest_before(k) else lo + int(np.argmin(d[lo : a + 1]))
        hi = min(b + search, k_len - 1)
        k = b
        while k < hi and not at_rest_after(k):
            k += 1
        end = k if at_rest_after(k) else b + int(np.argmin(d[b : hi + 1]))
        if candidates and start <= candidates[-1][2]:
            prev = candidates[-1]
            if d[peak] > d[prev[1]]:
                prev[1] = peak
            prev[2] = max(prev[2], end)
        else:
            candidates.append([start, peak, end])

    lifts = []
    for start, peak, end in candidates:
        # A lift cut by the recording's first or last sample (the recording started or
        # stopped mid-lift) is not a whole demonstration: fitted with the others, it
        # shifts the model's starting or final posture by the part that is missing.
        if (start == 0 and not at_rest_before(0)) or (
                end == k_len - 1 and not at_rest_after(k_len - 1)):
            continue
        duration = (end - start) * dt
        if not p.min_duration_s <= duration <= p.max_duration_s:
            continue
        if rel[peak].min() < p.min_each_hip_rad:
            continue
        lifts.append(SegmentedLift(start, peak, end))
    return lifts
