"""Quality flags on synthetic faults: each fault raises its flag, a clean channel none."""

from __future__ import annotations

import numpy as np
import pytest

from controller.emg.quality import (
    CLIPPING,
    DROPPED_SAMPLES,
    FLAT_LINE,
    MAINS,
    MOTION_ARTEFACT,
    NON_FINITE,
    RATE_MISMATCH,
    TIMESTAMPS_BACKWARDS,
    assess,
    assess_windows,
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
