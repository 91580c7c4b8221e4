"""The offline chain against closed forms, its properties, its settings, and the live
(causal) envelope against the offline one."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from controller.emg.processing import (
    RANGES,
    EmgProcessing,
    EmgSettingsError,
    EnvelopeStream,
    condition,
    design,
    fill_non_finite,
    process,
)
from tests.controller.emg.synthetic import band_noise

FS = 2000.0
EXACT = EmgProcessing(precision="float64")


def _amplitude_at(x: np.ndarray, f: float, fs: float) -> float:
    """Least-squares amplitude of the `f` Hz sinusoid in `x`."""
    t = np.arange(len(x)) / fs
    basis = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    return float(np.hypot(*coef))


def _butterworth_bandpass_gain(f: float, lo: float, hi: float, order: int, fs: float) -> float:
    """|H|^2 of a bilinear-transform Butterworth band-pass (scipy pre-warps both edges):
    the zero-phase (forward-backward) gain."""
    def warp(v: float) -> float:
        return 2 * fs * np.tan(np.pi * v / fs)
    w, wl, wh = warp(f), warp(lo), warp(hi)
    x = (w * w - wl * wh) / ((wh - wl) * w)
    return float(1.0 / (1.0 + x ** (2 * order)))


def test_rectified_sinusoid_envelope_is_two_a_over_pi() -> None:
    # A frequency incommensurate with fs: at exactly 100 Hz the 20 samples per period
    # always hit the same phases and their mean |sin| is cot(pi/20)/10, 0.8 % below 2/pi.
    a, f = 3e-4, 101.7
    t = np.arange(int(10 * FS)) / FS
    raw = (a * np.sin(2 * np.pi * f * t) + 5e-3)[:, None]  # with a DC offset
    env = process(raw, FS, EXACT)[int(2 * FS):-int(2 * FS), 0]
    gain = _butterworth_bandpass_gain(f, 20.0, 450.0, 4, FS)
    assert env.mean() == pytest.approx(2 * a * gain / np.pi, rel=1e-3)
    assert env.std() < 1e-3 * env.mean()  # the 200 Hz ripple is gone


def test_envelope_of_constant_amplitude_band_noise() -> None:
    sigma = 1e-4
    raw = band_noise(60_000, FS, (50.0, 150.0), sigma, channels=2)
    env = process(raw, FS, EXACT)[4000:-4000]
    # E|x| of a Gaussian is sigma * sqrt(2 / pi); the 50-150 Hz band is in the pass band.
    assert env.mean(axis=0) == pytest.approx([sigma * np.sqrt(2 / np.pi)] * 2, rel=0.02)
    # The 6 Hz envelope of a steady noise fluctuates, but far less than the signal.
    assert np.all(env.std(axis=0) < 0.25 * env.mean(axis=0))


@pytest.mark.parametrize("f", [8.0, 20.0, 35.0, 100.0, 300.0, 450.0, 600.0])
def test_bandpass_gain_matches_butterworth_magnitude(f: float) -> None:
    t = np.arange(int(20 * FS)) / FS
    raw = np.sin(2 * np.pi * f * t)[:, None]
    out = condition(raw, FS, EXACT)[int(5 * FS):-int(5 * FS), 0]
    expected = _butterworth_bandpass_gain(f, 20.0, 450.0, 4, FS)
    assert _amplitude_at(out, f, FS) == pytest.approx(expected, rel=2e-3, abs=1e-4)


def test_corner_gain_is_half_after_two_passes() -> None:
    assert _butterworth_bandpass_gain(20.0, 20.0, 450.0, 4, FS) == pytest.approx(0.5)


def test_trunk_preset_raises_the_high_pass() -> None:
    t = np.arange(int(20 * FS)) / FS
    raw = np.sin(2 * np.pi * 30.0 * t)[:, None]
    out = condition(raw, FS, EmgProcessing.trunk())[int(5 * FS):-int(5 * FS), 0]
    assert EmgProcessing.trunk().highpass_hz == 30.0
    assert _amplitude_at(out, 30.0, FS) == pytest.approx(0.5, rel=0.01)


def test_notch_removes_mains_and_keeps_the_rest() -> None:
    t = np.arange(int(20 * FS)) / FS
    raw = (np.sin(2 * np.pi * 50.0 * t) + np.sin(2 * np.pi * 120.0 * t))[:, None]
    notched = condition(raw, FS, EmgProcessing(notch_hz=50, precision="float64"))
    plain = condition(raw, FS, EXACT)
    mid = slice(int(5 * FS), -int(5 * FS))
    assert _amplitude_at(plain[mid, 0], 50.0, FS) > 0.99
    assert _amplitude_at(notched[mid, 0], 50.0, FS) < 1e-3  # better than -60 dB
    assert _amplitude_at(notched[mid, 0], 120.0, FS) == pytest.approx(
        _amplitude_at(plain[mid, 0], 120.0, FS), rel=0.02)


def test_float32_precision_stays_within_a_tenth_of_a_percent() -> None:
    raw = band_noise(40_000, FS, (20.0, 400.0), 1e-4, seed=3, channels=2) + 2e-3
    exact = process(raw, FS, EXACT)
    fast = process(raw, FS, EmgProcessing())
    assert fast.dtype == np.float64
    assert np.abs(fast - exact).max() < 2e-3 * exact.mean()


amplitudes = st.floats(min_value=1e-6, max_value=1e3).map(lambda v: v)


@settings(max_examples=15, deadline=None)
@given(k=amplitudes, negative=st.booleans(), seed=st.integers(0, 2**16))
def test_envelope_is_linear_in_amplitude(k: float, negative: bool, seed: int) -> None:
    raw = band_noise(4000, 1000.0, (20.0, 300.0), 1e-4, seed=seed, channels=2)
    base = process(raw, 1000.0, EXACT)
    scaled = process((-k if negative else k) * raw, 1000.0, EXACT)
    np.testing.assert_allclose(scaled, k * base, rtol=1e-9, atol=1e-12 * k * base.max())


@settings(max_examples=15, deadline=None)
@given(shift=st.integers(1, 600), seed=st.integers(0, 2**16))
def test_envelope_is_shift_equivariant_away_from_edges(shift: int, seed: int) -> None:
    fs = 1000.0
    raw = band_noise(5000, fs, (20.0, 300.0), 1e-4, seed=seed) + 1e-3
    whole = process(raw, fs, EXACT)
    later = process(raw[shift:], fs, EXACT)
    # Compare 1.5 s from either end of the shorter record: the zero-phase filters'
    # edge transients (padding, start-up) have decayed by then.
    edge = 1500
    a = whole[shift + edge:len(raw) - edge]
    b = later[edge:len(raw) - shift - edge]
    np.testing.assert_allclose(b, a, atol=1e-3 * whole.max())


def test_settings_round_trip_and_are_stable() -> None:
    s = EmgProcessing(highpass_hz=30.0, notch_hz=60, normalisation="task_peak")
    d = s.to_dict()
    assert d == {"version": 1, "remove_dc": True, "highpass_hz": 30.0, "lowpass_hz": 450.0,
                 "bandpass_order": 4, "notch_hz": 60, "notch_q": 30.0,
                 "rectification": "full_wave", "envelope_hz": 6.0, "envelope_order": 4,
                 "normalisation": "task_peak", "mvc_window_s": 0.5, "precision": "float32"}
    assert EmgProcessing.from_dict(d) == s
    assert EmgProcessing.from_dict({}) == EmgProcessing()


@pytest.mark.parametrize("bad", [
    {"highpass_hz": 500.0}, {"notch_hz": 55}, {"bandpass_order": 0}, {"envelope_hz": 0.0},
    {"normalisation": "peak"}, {"precision": "float16"}, {"unknown": 1}, {"version": 2},
    {"notch_hz": 50, "notch_q": 1e-300}, {"envelope_hz": 5000.0}, {"envelope_hz": 1e-300},
    {"highpass_hz": 1e307}, {"highpass_hz": True}, {"remove_dc": "no"},
    {"envelope_hz": float("nan")}, {"notch_hz": True}, {"mvc_window_s": "0.5"},
])
def test_bad_settings_say_what_is_wrong(bad: dict[str, object]) -> None:
    with pytest.raises(EmgSettingsError, match="EMG processing settings"):
        EmgProcessing.from_dict(bad)


def test_upper_edge_is_clipped_below_nyquist_and_low_rates_are_refused() -> None:
    d = design(EmgProcessing(), 800.0)
    assert d.lowpass_hz == pytest.approx(0.95 * 400.0)
    with pytest.raises(EmgSettingsError, match="too low"):
        design(EmgProcessing(), 200.0)


def test_non_finite_samples_are_refused_with_where_and_filled_only_on_request() -> None:
    raw = band_noise(4000, FS, (20.0, 300.0), 1e-4, channels=3)
    raw[1234, 2] = np.nan
    with pytest.raises(ValueError, match="channel 2 at sample 1234"):
        process(raw, FS, EXACT)
    filled, mask = fill_non_finite(raw)
    assert mask.sum() == 1 and mask[1234, 2]
    assert filled[1234, 2] == pytest.approx((raw[1233, 2] + raw[1235, 2]) / 2)


def test_too_short_a_record_is_refused() -> None:
    with pytest.raises(ValueError, match="at least"):
        process(np.zeros((10, 1)), FS, EXACT)


def test_live_envelope_does_not_depend_on_block_sizes() -> None:
    raw = band_noise(6000, FS, (20.0, 400.0), 1e-4, channels=2) + 1e-3
    whole = EnvelopeStream(FS, 2).push(raw)
    stream = EnvelopeStream(FS, 2)
    cuts = [0, 1, 17, 500, 501, 3000, 6000]
    parts = [stream.push(raw[a:b]) for a, b in zip(cuts, cuts[1:], strict=False)]
    np.testing.assert_allclose(np.vstack(parts), whole, rtol=1e-10, atol=1e-15)


def test_live_envelope_settles_on_the_offline_one_for_a_steady_sinusoid() -> None:
    t = np.arange(int(6 * FS)) / FS
    raw = np.column_stack([2e-4 * np.sin(2 * np.pi * 87.3 * t) + 1e-3,
                           5e-5 * np.sin(2 * np.pi * 211.9 * t) - 4e-3])
    stream = EnvelopeStream(FS, 2, EXACT)
    live = np.vstack([stream.push(raw[i:i + 40]) for i in range(0, len(raw), 40)])
    offline = process(raw, FS, EXACT)
    steady = slice(int(1.5 * FS), -int(1.5 * FS))  # start-up of both, padding of offline
    level = offline[steady].mean(axis=0)
    # The envelope of a steady signal is constant: lag does not matter, and both
    # filters have a DC gain of one, so the causal one differs only by its ripple.
    assert np.all(np.abs(live[steady] - offline[steady]).max(axis=0) < 0.005 * level)


def test_live_envelope_of_steady_noise_has_the_offline_level() -> None:
    raw = band_noise(40_000, FS, (30.0, 300.0), 1e-4, seed=5, channels=2) + 2e-3
    stream = EnvelopeStream(FS, 2, EXACT)
    live = np.vstack([stream.push(raw[i:i + 40]) for i in range(0, len(raw), 40)])
    offline = process(raw, FS, EXACT)
    steady = slice(int(2 * FS), -int(2 * FS))
    level = offline[steady].mean(axis=0)
    assert live[steady].mean(axis=0) == pytest.approx(level, rel=0.02)
    # Sample by sample they differ by the lag and the single-pass response, on the
    # scale of the envelope's own fluctuation (its standard deviation).
    spread = offline[steady].std(axis=0)
    assert np.all(np.sqrt(np.mean((live[steady] - offline[steady]) ** 2, axis=0))
                  < 2.0 * spread)


def test_live_envelope_counts_and_holds_non_finite_samples() -> None:
    raw = band_noise(2000, FS, (20.0, 400.0), 1e-4, channels=1)
    bad = raw.copy()
    bad[700:703, 0] = [np.nan, np.inf, np.nan]
    held = raw.copy()
    held[700:703, 0] = raw[699, 0]
    stream = EnvelopeStream(FS, 1)
    out = stream.push(bad)
    assert stream.non_finite_samples == 3
    np.testing.assert_allclose(out, EnvelopeStream(FS, 1).push(held))


@pytest.mark.parametrize(("field", "value"), [
    ("notch_q", 1e-300), ("envelope_hz", 5000.0), ("envelope_hz", 1e-300),
    ("highpass_hz", 1e307), ("mvc_window_s", 60.0)])
def test_out_of_range_settings_name_the_field_range_and_reason(field: str,
                                                              value: float) -> None:
    lo, hi, why = RANGES[field]
    with pytest.raises(EmgSettingsError) as err:
        EmgProcessing.from_dict({field: value})
    assert f"{field} must be from {lo:g} to {hi:g}" in str(err.value)
    assert why in str(err.value)


@given(st.floats(allow_nan=True, allow_infinity=True))
@settings(max_examples=40, deadline=None)
def test_any_accepted_setting_designs_finite_filters(q: float) -> None:
    """Whatever notch_q is accepted, the filters it gives are finite."""
    try:
        proc = EmgProcessing(notch_hz=50, notch_q=q)
    except EmgSettingsError:
        return
    d = design(proc, 2000.0)
    assert np.isfinite(d.bandpass).all() and np.isfinite(d.envelope).all()


class _ScipyEnvelopeStream:
    """The live envelope as it was computed before the compiled pass: the same hold of
    non-finite samples, then scipy's `sosfilt` per filter with its `zi` carried over."""

    def __init__(self, fs: float, n_channels: int, proc: EmgProcessing) -> None:
        self.design = design(proc, fs)
        self.bp_zi: np.ndarray | None = None
        self.env_zi = np.zeros((len(self.design.envelope), 2, n_channels))
        self.last = np.zeros(n_channels)

    def push(self, block: np.ndarray) -> np.ndarray:
        arr = np.asarray(block, dtype=np.float64)
        if arr.shape[0] == 0:
            return np.empty((0, arr.shape[1]))
        bad = ~np.isfinite(arr)
        if bad.any():
            arr = arr.copy()
            for c in np.nonzero(bad.any(axis=0))[0]:
                col = arr[:, c]
                held = np.maximum.accumulate(np.where(bad[:, c], -1, np.arange(len(col))))
                arr[:, c] = np.where(held >= 0, col[np.maximum(held, 0)], self.last[c])
        self.last = arr[-1].copy()
        if self.bp_zi is None:
            zi = signal.sosfilt_zi(self.design.bandpass)
            self.bp_zi = zi[:, :, None] * arr[0][None, None, :]
        y, self.bp_zi = signal.sosfilt(self.design.bandpass, arr, axis=0, zi=self.bp_zi)
        env, self.env_zi = signal.sosfilt(self.design.envelope, np.abs(y), axis=0,
                                          zi=self.env_zi)
        return np.asarray(env)


@settings(max_examples=30, deadline=None)
@given(sizes=st.lists(st.integers(0, 700), min_size=1, max_size=12),
       channels=st.integers(1, 18), seed=st.integers(0, 2**32 - 1),
       notch=st.sampled_from([None, 50, 60]), fs=st.sampled_from([1000.0, 2000.0, 4096.0]),
       holes=st.integers(0, 6))
def test_live_envelope_equals_scipys_sosfilt_bit_for_bit(
        sizes: list[int], channels: int, seed: int, notch: int | None, fs: float,
        holes: int) -> None:
    rng = np.random.default_rng(seed)
    n = sum(sizes)
    raw = rng.normal(0, 1e-4, (n, channels)) + rng.uniform(-5e-3, 5e-3, channels)
    for _ in range(holes if n else 0):  # NaN and infinities, held by both
        raw[rng.integers(n), rng.integers(channels)] = rng.choice([np.nan, np.inf, -np.inf])
    proc = EmgProcessing(notch_hz=notch)
    new, old = EnvelopeStream(fs, channels, proc), _ScipyEnvelopeStream(fs, channels, proc)
    k = 0
    for size in sizes:
        block = raw[k:k + size]
        k += size
        np.testing.assert_array_equal(new.push(block), old.push(block))
