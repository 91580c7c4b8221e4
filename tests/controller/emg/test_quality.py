"""Quality flags on synthetic faults: each fault raises its flag, a clean channel none."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from controller.emg import quality
from controller.emg.quality import (
    CLIPPING,
    DROPPED_SAMPLES,
    FLAT_LINE,
    MAINS,
    MOTION_ARTEFACT,
    NON_FINITE,
    RATE_MISMATCH,
    TIMESTAMPS_BACKWARDS,
    ChannelQuality,
    assess,
    assess_windows,
    channel_quality,
    clipped_counts,
    dc_removed_rms,
    timing_quality,
)
from tests.controller.emg.synthetic import band_noise

FS = 2000.0
N = int(10 * FS)


def _clean(seed: int = 0) -> np.ndarray:
    return band_noise(N, FS, (20.0, 450.0), 1e-4, seed=seed, channels=1)[:, 0] + 1e-3


@pytest.mark.parametrize("seed", range(5))
def test_clean_emg_raises_no_flag(seed: int) -> None:
    t = np.arange(N) / FS
    report = assess(_clean(seed)[:, None], FS, timestamps=100.0 + t)
    assert report.flags == ()


def test_each_fault_raises_its_flag_on_its_channel_only() -> None:
    t = np.arange(N) / FS
    clean = _clean()
    clipped = np.clip(clean, -1.5e-4 + 1e-3, 1.5e-4 + 1e-3)
    flat = np.full(N, 2.5e-3)
    hum = clean + 5e-5 * np.sin(2 * np.pi * 60.0 * t)
    motion = clean + 3e-4 * np.sin(2 * np.pi * 2.0 * t)
    nan = clean.copy()
    nan[[10, 500]] = [np.nan, np.inf]
    raw = np.column_stack([clean, clipped, flat, hum, motion, nan])
    report = assess(raw, FS)
    assert [c.flags for c in report.channels] == [
        (), (CLIPPING,), (FLAT_LINE,), (MAINS,), (MOTION_ARTEFACT,), (NON_FINITE,)]
    assert report.channels[3].mains_hz == 60
    assert report.channels[5].non_finite == 2
    assert report.channels[1].clipped_samples > 50  # runs of 4 or more at the rails
    assert report.timing is None


def test_clipping_against_a_known_input_range() -> None:
    x = _clean()
    x[5000:5010] = 2e-3          # saturated at the amplifier's rail for 10 samples
    x[7000] = -2e-3              # and for one sample at the other
    report = assess(x[:, None], FS, input_range=(-2e-3, 2e-3))
    assert report.channels[0].clipped_samples == 11
    assert report.channels[0].flags == (CLIPPING,)
    assert assess(_clean()[:, None], FS, input_range=(-2e-3, 2e-3)).flags == ()


def test_mains_hum_below_threshold_is_not_flagged_and_50_hz_is_named() -> None:
    t = np.arange(N) / FS
    faint = _clean() + 1e-7 * np.sin(2 * np.pi * 50.0 * t)
    strong = _clean() + 3e-5 * np.sin(2 * np.pi * 50.0 * t)
    report = assess(np.column_stack([faint, strong]), FS, mains_hz=50)
    assert report.channels[0].flags == ()
    assert report.channels[1].flags == (MAINS,)
    assert report.channels[1].mains_hz == 50


def test_gaps_rate_and_restarts_from_timestamps() -> None:
    t = np.arange(10_000) / FS
    gappy = np.concatenate([t[:4000], t[4007:]])  # 7 samples lost
    q = timing_quality(gappy, FS)
    assert (q.gaps, q.dropped_samples, q.flags) == (1, 7, (DROPPED_SAMPLES,))
    assert q.rate_from_timestamps_hz == pytest.approx(FS)
    wrong = timing_quality(np.arange(10_000) / 2048.0, FS)
    assert wrong.flags == (RATE_MISMATCH,)
    assert wrong.rate_from_timestamps_hz == pytest.approx(2048.0)
    jitter = t + np.random.default_rng(0).uniform(-0.2, 0.2, t.size) / FS
    assert timing_quality(jitter, FS).flags == ()
    restarted = np.concatenate([t[:5000], t[:5000]])
    assert TIMESTAMPS_BACKWARDS in timing_quality(restarted, FS).flags


def test_windows_are_assessed_separately() -> None:
    x = _clean()
    x[12000:16000] = 1e-3            # electrode off during the second trial
    reports = assess_windows(x[:, None], FS, [(0, 8000), (10000, 18000)],
                             timestamps=np.arange(N) / FS)
    assert reports[0].flags == ()
    assert reports[1].channels[0].rms_v < reports[0].channels[0].rms_v
    flat = assess_windows(x[:, None], FS, [(12000, 16000)])
    assert flat[0].flags == (FLAT_LINE,)


def test_report_is_plain_data() -> None:
    report = assess(_clean()[:, None], FS, timestamps=np.arange(N) / FS)
    d = report.to_dict()
    assert d["channels"][0]["flags"] == []
    assert d["timing"]["dropped_samples"] == 0


@pytest.mark.parametrize("factor", [0.5, 2.0, 0.25])
def test_a_stream_stamped_at_another_rate_is_a_rate_mismatch_not_dropped_samples(
        factor: float) -> None:
    """The attack: stamps at half the nominal rate were read as every other sample
    lost. The stamps' own spacing is the period then; the flag is rate_mismatch."""
    q = timing_quality(np.arange(4000) / (FS * factor), FS)
    assert q.flags == (RATE_MISMATCH,) and q.dropped_samples == 0
    assert q.rate_from_timestamps_hz == pytest.approx(FS * factor)
    # Losses in such a stream still count, in its own period.
    t = np.arange(4000) / (FS * factor)
    q = timing_quality(np.concatenate([t[:1000], t[1010:]]), FS)
    assert q.dropped_samples == 10 and DROPPED_SAMPLES in q.flags


# The per-channel measurements as they were computed one channel at a time, kept as the
# reference the channels-together computation must equal exactly.
def _old_runs_at(mask: np.ndarray, min_run: int) -> int:
    if not mask.any():
        return 0
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.diff(padded)
    starts, stops = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    lengths = stops - starts
    return int(lengths[lengths >= min_run].sum())


def _old_clipped(x: np.ndarray, input_range: tuple[float, float] | None) -> int:
    finite = x[np.isfinite(x)]
    if finite.size == 0:
        return 0
    low, high = input_range if input_range is not None else (finite.min(), finite.max())
    span = high - low
    if span <= 0:
        return 0
    tol = quality.CLIPPING_TOLERANCE * span
    with np.errstate(invalid="ignore"):
        at_high = x >= high - tol
        at_low = x <= low + tol
    run = 1 if input_range is not None else quality.CLIPPING_MIN_RUN
    return _old_runs_at(at_high, run) + _old_runs_at(at_low, run)


def _old_channel(x: np.ndarray, fs: float, channel: int,
                 input_range: tuple[float, float] | None,
                 mains_hz: int | None) -> ChannelQuality:
    raw = np.asarray(x, dtype=np.float64)
    finite = np.isfinite(raw)
    non_finite = int((~finite).sum())
    flags: list[str] = [NON_FINITE] if non_finite else []
    good = raw[finite]
    if good.size < 2:
        return ChannelQuality(channel, len(raw), non_finite, 0.0, 0, 0.0, 0, 0.0,
                              (*flags, FLAT_LINE))
    centred = good - good.mean()
    rms = float(np.sqrt(np.mean(centred**2)))
    clipped = _old_clipped(raw, input_range)
    if clipped:
        flags.append(CLIPPING)
    if rms < quality.FLAT_LINE_RMS_V:
        flags.append(FLAT_LINE)
        return ChannelQuality(channel, len(raw), non_finite, rms, clipped, 0.0, 0, 0.0,
                              tuple(flags))
    nperseg = min(len(centred), max(8, round(quality.WELCH_SEGMENT_S * fs)))
    f, p = signal.welch(centred, fs=fs, nperseg=nperseg, detrend="constant")
    candidates = [mains_hz] if mains_hz is not None else [50, 60]
    ratios = [(quality.mains_ratio(f, p, m), m) for m in candidates if m < fs / 2]
    ratio, hz = max(ratios) if ratios else (0.0, 0)
    if ratio > quality.MAINS_RATIO:
        flags.append(MAINS)
    total = float(p[1:].sum())
    low = float(p[1:][f[1:] < quality.MOTION_CUTOFF_HZ].sum())
    share = low / total if total > 0 else 0.0
    if share > quality.MOTION_SHARE:
        flags.append(MOTION_ARTEFACT)
    return ChannelQuality(channel, len(raw), non_finite, rms, clipped, float(ratio), int(hz),
                          share, tuple(flags))


def _channel(kind: str, n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(n) / fs
    noise = rng.normal(0, 1e-4, n) + rng.uniform(-3e-3, 3e-3)
    out: dict[str, Any] = {
        "noise": lambda: noise,
        "constant": lambda: np.full(n, rng.uniform(-1e-3, 1e-3)),
        "near_flat": lambda: 2.5e-3 + rng.normal(0, rng.choice([5e-8, 1e-7, 2e-7]), n),
        "clipped": lambda: np.clip(noise, np.quantile(noise, 0.1) if n else 0,
                                   np.quantile(noise, 0.9) if n else 0),
        "hum": lambda: noise + 5e-5 * np.sin(2 * np.pi * rng.choice([50, 60]) * t),
        "motion": lambda: noise + 3e-4 * np.sin(2 * np.pi * 2.0 * t),
        "steps": lambda: np.repeat(rng.normal(0, 1e-4, n // 5 + 1), 5)[:n],
    }
    return np.asarray(out[kind](), dtype=np.float64)


@settings(max_examples=40, deadline=None)
@given(n=st.one_of(st.integers(0, 12), st.integers(13, 6000)),
       kinds=st.lists(st.sampled_from(["noise", "constant", "near_flat", "clipped", "hum",
                                       "motion", "steps"]), min_size=1, max_size=6),
       holes=st.lists(st.sampled_from([np.nan, np.inf, -np.inf]), max_size=8),
       fs=st.sampled_from([2000.0, 1000.0, 100.0, 4096.0]),
       mains_hz=st.sampled_from([None, 50, 60]),
       input_range=st.sampled_from([None, (-2e-3, 2e-3), (1.0, 1.0)]),
       seed=st.integers(0, 2**32 - 1))
def test_channels_together_equal_one_at_a_time(
        n: int, kinds: list[str], holes: list[float], fs: float, mains_hz: int | None,
        input_range: tuple[float, float] | None, seed: int) -> None:
    rng = np.random.default_rng(seed)
    raw = np.column_stack([_channel(k, n, fs, rng) for k in kinds]).reshape(n, len(kinds))
    for value in holes if n else []:
        raw[rng.integers(n), rng.integers(len(kinds))] = value
    if n > 3 and rng.integers(3) == 0:  # a channel with nothing finite at all
        raw[:, rng.integers(len(kinds))] = np.nan
    expected = tuple(_old_channel(raw[:, c], fs, c, input_range, mains_hz)
                     for c in range(len(kinds)))
    assert assess(raw, fs, input_range=input_range, mains_hz=mains_hz).channels == expected
    assert channel_quality(raw[:, -1], fs, 7, input_range, mains_hz) == (
        _old_channel(raw[:, -1], fs, 7, input_range, mains_hz))
    np.testing.assert_array_equal(
        clipped_counts(raw, input_range),
        [_old_clipped(raw[:, c], input_range) for c in range(len(kinds))])
    rms = [np.sqrt(np.mean((g - g.mean()) ** 2)) if g.size else np.nan
           for g in (raw[np.isfinite(raw[:, c]), c] for c in range(len(kinds)))]
    np.testing.assert_array_equal(dc_removed_rms(raw), rms)
