"""Tests of lift segmentation on synthetic recordings with known lifts."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.intent.segmentation import SegmentationParams, SegmentedLift, segment_lifts

FS = 100.0
NOISE_RAD = np.radians(0.06)
TOL = 6  # samples (60 ms)


def min_jerk(n: int) -> np.ndarray:
    """0 -> 1 over n samples with zero velocity and acceleration at both ends."""
    x = np.linspace(0.0, 1.0, n)
    return 10 * x**3 - 15 * x**4 + 6 * x**5


@dataclass
class Truth:
    start: int
    peak_lo: int
    peak_hi: int
    end: int


@dataclass
class RecordingBuilder:
    """Builds a recording piece by piece and remembers where the lifts are."""

    parts: list[np.ndarray] = field(default_factory=list)
    lifts: list[Truth] = field(default_factory=list)

    @property
    def length(self) -> int:
        return sum(len(p) for p in self.parts)

    def rest(self, seconds: float) -> RecordingBuilder:
        self.parts.append(np.zeros((int(seconds * FS), 2)))
        return self

    def lift(self, peak_l: float, peak_r: float, down: float = 1.2, hold: float = 0.3,
             up: float = 1.3) -> RecordingBuilder:
        n1, nh, n2 = int(down * FS), int(hold * FS), int(up * FS)
        peak = np.array([peak_l, peak_r])
        seg = np.vstack([
            min_jerk(n1)[:, None] * peak,
            np.repeat(peak[None, :], nh, axis=0),
            (1.0 - min_jerk(n2))[:, None] * peak,
        ])
        k0 = self.length
        # Motion starts after sample k0 (seg[0] is still at rest), ends at seg[-1].
        self.lifts.append(Truth(k0, k0 + n1 - 1, k0 + n1 + nh, k0 + len(seg) - 1))
        self.parts.append(seg)
        return self

    def walk(self, seconds: float, stride: float = 1.1,
             range_deg: float = 36.0) -> RecordingBuilder:
        n = int(seconds * FS)
        t = np.arange(n) / FS
        env = np.clip(np.minimum(t, seconds - t) / 1.0, 0.0, 1.0)  # 1 s ramps in and out
        amp = np.radians(range_deg) / 2
        mid = np.radians(10.0)
        ph = 2 * np.pi * t / stride
        left = env * (mid + amp * np.sin(ph) + np.radians(3.0) * np.sin(2 * ph))
        right = env * (mid + amp * np.sin(ph + np.pi) + np.radians(3.0) * np.sin(2 * ph))
        self.parts.append(np.column_stack([left, right]))
        return self

    def stairs(self, steps: int, step_s: float = 0.9) -> RecordingBuilder:
        """Stair ascent: the leading hip flexes ~63 deg, the other stays low."""
        n = int(step_s * FS)
        bump = np.sin(np.pi * np.arange(n) / n) ** 2
        for i in range(steps):
            lead = np.radians(63.0) * bump
            trail = np.radians(8.0) * bump
            pair = [lead, trail] if i % 2 == 0 else [trail, lead]
            self.parts.append(np.column_stack(pair))
        return self

    def build(self, seed: int = 0, drift_rad_per_s: float = np.radians(0.05),
              offset: tuple[float, float] = (0.06, -0.04)) -> tuple[np.ndarray, np.ndarray]:
        q = np.vstack(self.parts)
        k = len(q)
        t = np.arange(k) / FS
        rng = np.random.default_rng(seed)
        q = q + np.asarray(offset) + drift_rad_per_s * t[:, None] * np.array([1.0, -0.7])
        q = q + rng.normal(0.0, NOISE_RAD, q.shape)
        return t, q


def check(found: list[SegmentedLift], truth: list[Truth]) -> None:
    assert len(found) == len(truth), (found, truth)
    for seg, tr in zip(found, truth, strict=True):
        assert abs(seg.start - tr.start) <= TOL, (seg, tr)
        assert abs(seg.end - tr.end) <= TOL, (seg, tr)
        assert tr.peak_lo - TOL <= seg.peak <= tr.peak_hi + TOL, (seg, tr)


def test_lifts_with_pauses_drift_and_walking() -> None:
    rec = (
        RecordingBuilder().rest(3.0)
        .lift(1.75, 1.75)  # squat
        .rest(1.5)
        .lift(1.65, 1.15, down=1.0, up=1.1)  # stoop left
        .rest(2.5)
        .walk(12.0)
        .rest(2.0)
        .lift(1.1, 1.6, down=1.4, hold=0.0, up=1.5)  # stoop right, no hold
        .rest(1.0)
        .lift(1.9, 1.85, hold=0.8)
        .rest(3.0)
    )
    t, q = rec.build(seed=1)
    check(segment_lifts(t, q), rec.lifts)


def test_walking_and_stairs_give_no_lift() -> None:
    rec = RecordingBuilder().rest(2.0).walk(20.0, range_deg=42.0).rest(1.0).stairs(11).rest(2.0)
    t, q = rec.build(seed=2)
    assert segment_lifts(t, q) == []


def test_walking_straight_into_lifts_without_standing_still() -> None:
    """No quiet spell before the lift's onset: the baseline comes from elsewhere."""
    rec = RecordingBuilder().rest(2.0).walk(6.0).rest(0.4).lift(1.7, 1.7).rest(2.0)
    t, q = rec.build(seed=3)
    check(segment_lifts(t, q), rec.lifts)


@settings(max_examples=12, deadline=None)
@given(
    kinds=st.lists(st.sampled_from(["squat", "stoop_left", "stoop_right", "walk"]),
                   min_size=1, max_size=5),
    seed=st.integers(0, 10_000),
)
def test_random_sessions(kinds: list[str], seed: int) -> None:
    rng = np.random.default_rng(seed)
    rec = RecordingBuilder().rest(float(rng.uniform(1.5, 3.0)))
    for kind in kinds:
        if kind == "walk":
            rec.walk(float(rng.uniform(4.0, 10.0)), stride=float(rng.uniform(1.0, 1.2)),
                     range_deg=float(rng.uniform(30.0, 45.0)))
        else:
            big = float(rng.uniform(np.radians(75), np.radians(110)))
            small = big if kind == "squat" else float(rng.uniform(np.radians(60), big - 0.2))
            pl, pr = (big, small) if kind != "stoop_right" else (small, big)
            rec.lift(pl, pr, down=float(rng.uniform(1.0, 1.5)), hold=float(rng.uniform(0, 0.6)),
                     up=float(rng.uniform(1.0, 1.5)))
        rec.rest(float(rng.uniform(1.0, 3.0)))
    drift = float(rng.uniform(-1.0, 1.0)) * np.radians(0.1)
    offset = (float(rng.uniform(-0.1, 0.1)), float(rng.uniform(-0.1, 0.1)))
    t, q = rec.build(seed=seed, drift_rad_per_s=drift, offset=offset)
    check(segment_lifts(t, q), rec.lifts)


def test_five_times_the_encoder_noise_still_finds_every_lift() -> None:
    rec = (RecordingBuilder().rest(2.0).lift(1.6, 1.6).rest(1.5).walk(8.0).rest(1.5)
           .lift(1.5, 1.1).rest(2.0))
    t, q = rec.build(seed=9)
    q = q + np.random.default_rng(10).normal(0.0, 4 * NOISE_RAD, q.shape)
    found = segment_lifts(t, q)
    assert len(found) == 2
    for seg, tr in zip(found, rec.lifts, strict=True):
        assert abs(seg.start - tr.start) <= 2 * TOL and abs(seg.end - tr.end) <= 2 * TOL


def test_returns_plain_editable_indices() -> None:
    rec = RecordingBuilder().rest(2.0).lift(1.7, 1.7).rest(2.0)
    t, q = rec.build()
    (seg,) = segment_lifts(t, q)
    assert all(type(v) is int for v in (seg.start, seg.peak, seg.end))
    demo = q[seg.as_slice()]
    assert demo.shape[0] == seg.end - seg.start + 1
    np.testing.assert_array_equal(demo[[0, -1]], q[[seg.start, seg.end]])
    with pytest.raises(ValueError):
        SegmentedLift(10, 5, 20)


def test_stricter_threshold_drops_shallow_lifts() -> None:
    rec = RecordingBuilder().rest(2.0).lift(1.0, 1.0).rest(2.0).lift(1.8, 1.8).rest(2.0)
    t, q = rec.build()
    assert len(segment_lifts(t, q)) == 2
    strict = SegmentationParams(detect_rad=np.radians(70.0))
    (only,) = segment_lifts(t, q, strict)
    assert abs(only.start - rec.lifts[1].start) <= TOL


@pytest.mark.parametrize("cut", ["start", "end"])
def test_a_lift_cut_by_the_recording_edge_is_left_out(cut: str) -> None:
    """A recording that starts (or stops) mid-lift holds only part of that lift; the
    whole lifts beside it are still found."""
    rec = RecordingBuilder().rest(2.0).lift(1.6, 1.5).rest(2.0).lift(1.4, 1.5).rest(2.0)
    t, q = rec.build(seed=3)
    whole = rec.lifts
    if cut == "start":
        k = whole[0].peak_lo + 20  # rising out of the first lift's peak
        t, q, kept = t[k:] - t[k], q[k:], [Truth(tr.start - k, tr.peak_lo - k,
                                                  tr.peak_hi - k, tr.end - k)
                                            for tr in whole[1:]]
    else:
        k = whole[1].peak_lo - 20  # still going down into the second lift
        t, q, kept = t[:k], q[:k], whole[:1]
    check(segment_lifts(t, q), kept)
    check(segment_lifts(*rec.build(seed=3)), whole)  # uncut: both


def test_input_validation() -> None:
    t = np.arange(100) / FS
    with pytest.raises(ValueError, match=r"q \(K, 2\)"):
        segment_lifts(t, np.zeros((100, 3)))
    q = np.zeros((100, 2))
    q[3, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        segment_lifts(t, q)
    with pytest.raises(ValueError, match="increasing"):
        segment_lifts(t[::-1], np.zeros((100, 2)))
    with pytest.raises(ValueError, match="shorter"):
        segment_lifts(t[:5], np.zeros((5, 2)))
    with pytest.raises(ValueError, match="rest_tol_rad"):
        SegmentationParams(rest_tol_rad=1.0)
    assert segment_lifts(t, np.zeros((100, 2))) == []
