"""Simulated surface EMG against its own generating truth: band, amplitude, envelope,
artefacts, faults, and reproducibility by seed and by block size."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy import signal

from controller.sim.surface_emg import (
    EmgSettings,
    Faults,
    SurfaceEmgGenerator,
    generate,
)

FS = 2000.0
QUIET = EmgSettings(mains_hz=None)  # no hum: tests of the muscle part alone


def _lifts(n_ticks: int, channels: int = 4) -> np.ndarray:
    """Tick-rate activation: slow lift-like bumps (2 s period) of different heights."""
    t = np.arange(n_ticks) / 100.0
    bump = 0.5 - 0.5 * np.cos(2 * np.pi * t / 2.0)
    heights = np.linspace(0.2, 0.9, channels)
    return 0.02 + bump[:, None] * heights[None, :]


def _envelope(x: np.ndarray, window: int = 200) -> np.ndarray:
    """The test's own envelope: remove the mean, rectify, moving average (0.1 s)."""
    rect = np.abs(x - x.mean(axis=0))
    kernel = np.ones(window) / window
    return np.stack([np.convolve(rect[:, c], kernel, mode="same") for c in range(x.shape[1])], 1)


def test_spectrum_lies_within_20_to_450_hz() -> None:
    out = generate(np.full((1000, 3), 0.5), seed=1)
    f, p = signal.welch(out.samples, fs=FS, nperseg=2048, axis=0)
    band = (f >= 20) & (f <= 450)
    share = p[band].sum(axis=0) / p.sum(axis=0)
    # A 4th-order Butterworth's skirts leave a few % just outside the corners.
    assert np.all(share > 0.9), share
    far = np.median(p[(f > 700) | (f < 5)], axis=0)
    assert np.all(np.median(p[band], axis=0) > 100 * far)


def test_rms_matches_the_generating_amplitude() -> None:
    out = generate(np.full((2000, 4), 0.6), seed=2, settings=QUIET)
    rms = np.sqrt(np.mean(out.samples**2, axis=0))
    np.testing.assert_allclose(rms, out.amplitude_v[0], rtol=0.03)
    assert np.all((out.gain_v >= 0.5e-3) & (out.gain_v <= 1.5e-3))  # 1 mV x 0.5-1.5


def test_envelope_tracks_activation() -> None:
    act = _lifts(3000)
    out = generate(act, seed=3)
    env = _envelope(out.samples)
    for c in range(act.shape[1]):
        r = np.corrcoef(env[200:-200, c], out.activation[200:-200, c])[0, 1]
        assert r > 0.95, (c, r)
        # Normalised by the gain, the rectified mean is sqrt(2/pi) of the RMS.
        ratio = env[200:-200, c].mean() / out.amplitude_v[200:-200, c].mean()
        assert ratio == pytest.approx(np.sqrt(2 / np.pi), rel=0.06)


def test_reproducible_by_seed_and_independent_of_block_size() -> None:
    act = _lifts(300, 16)
    a = generate(act, seed=5, block_ticks=1000)
    b = generate(act, seed=5, block_ticks=7)
    np.testing.assert_allclose(a.samples, b.samples, rtol=0, atol=1e-12)
    gen = SurfaceEmgGenerator(16, seed=5)
    ticks = np.concatenate([gen.push(row).samples for row in act])
    np.testing.assert_allclose(ticks, a.samples, rtol=0, atol=1e-12)
    c = generate(act, seed=6)
    assert not np.allclose(a.samples, c.samples)


@settings(max_examples=30, deadline=None)
@given(hnp.arrays(np.float64, st.tuples(st.integers(1, 40), st.integers(1, 5)),
                  elements=st.floats(0.0, 1.0)), st.integers(0, 2**32 - 1))
def test_any_activation_gives_finite_samples_and_its_truth(act: np.ndarray, seed: int) -> None:
    out = generate(act, seed=seed)
    assert out.samples.shape == (act.shape[0] * 20, act.shape[1])
    assert np.all(np.isfinite(out.samples))
    # Every tick's last sample carries that tick's activation exactly.
    np.testing.assert_allclose(out.activation[19::20], act)
    np.testing.assert_allclose(out.t, np.arange(out.t.size) / FS)


def test_mains_hum_on_a_channel_without_muscle() -> None:
    for hz in (50.0, 60.0):
        out = generate(np.zeros((1000, 2)), seed=1, settings=EmgSettings(mains_hz=hz))
        f, p = signal.welch(out.samples[:, 0], fs=FS, nperseg=4000)
        assert f[np.argmax(p)] == pytest.approx(hz, abs=0.5)
    with pytest.raises(ValueError, match="mains_hz"):
        EmgSettings(mains_hz=55.0)


def test_movement_onset_adds_a_low_frequency_artefact() -> None:
    act = np.full((400, 2), 0.1)
    plain = generate(act, seed=4, settings=QUIET)
    moved = generate(act, seed=4, settings=QUIET, onsets=[100])
    diff = moved.samples - plain.samples
    assert np.all(diff[:2000] == 0)  # nothing before the onset
    f, p = signal.welch(diff[2000:5000], fs=FS, nperseg=2048, axis=0)
    assert np.all(p[f < 20].sum(axis=0) > 0.99 * p.sum(axis=0))
    assert np.abs(diff).max() > 20e-6


def test_faults_clip_flatten_drop_and_stop() -> None:
    act = np.full((200, 3), 0.8)
    clipped = generate(act, seed=1, settings=EmgSettings(faults=Faults(clip_v=0.2e-3)))
    assert np.abs(clipped.samples).max() == pytest.approx(0.2e-3)
    flat = generate(act, seed=1, settings=EmgSettings(faults=Faults(flat=(1,))))
    assert np.all(flat.samples[:, 1] == 0) and np.std(flat.samples[:, 0]) > 0
    dropped = generate(act, seed=1, settings=EmgSettings(faults=Faults(drop_every=5)))
    assert dropped.t.size == 4000 - 800
    assert np.max(np.diff(dropped.t)) == pytest.approx(21 / FS)
    stopped = generate(act, seed=1, settings=EmgSettings(faults=Faults(stop_after_s=1.0)))
    assert stopped.t.size == 2000 and stopped.t[-1] < 1.0


def test_bad_settings_and_input_are_refused() -> None:
    with pytest.raises(ValueError, match="band"):
        EmgSettings(fs=500.0)
    gen = SurfaceEmgGenerator(2)
    with pytest.raises(ValueError, match="channels"):
        gen.push(np.zeros((1, 3)))
    with pytest.raises(ValueError, match="finite"):
        gen.push(np.array([[np.nan, 0.0]]))
