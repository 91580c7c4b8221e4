"""The in-place multi-channel zero-phase kernel against scipy's `sosfiltfilt`, channel by
channel, for the chain's filters, partial channel blocks, threads and both precisions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from controller.emg.zero_phase import CausalEnvelope, pad_length, zero_phase

FS = 2000.0
BANDPASS = np.vstack([signal.butter(4, [20, 450], btype="bandpass", fs=FS, output="sos"),
                      signal.tf2sos(*signal.iirnotch(50.0, 30.0, fs=FS))])
ENVELOPE = signal.butter(4, 6.0, fs=FS, output="sos")


def _scipy(sos: np.ndarray, x: np.ndarray, offset: np.ndarray, rectify: bool) -> np.ndarray:
    out = np.empty_like(x)
    for c in range(x.shape[1]):
        col = (x[:, c] - offset[c]).astype(sos.dtype)
        out[:, c] = signal.sosfiltfilt(sos, np.abs(col) if rectify else col)
    return out


@settings(max_examples=20, deadline=None)
@given(channels=st.integers(1, 19), n=st.integers(200, 3000), seed=st.integers(0, 2**16),
       lanes=st.sampled_from([1, 3, 8, 16]), threads=st.integers(1, 3),
       precision=st.sampled_from([np.float32, np.float64]), rectify=st.booleans(),
       envelope=st.booleans())
def test_matches_sosfiltfilt_per_channel(channels: int, n: int, seed: int, lanes: int,
                                         threads: int, precision: type, rectify: bool,
                                         envelope: bool) -> None:
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((n, channels)) * 1e-4 + rng.uniform(-5e-3, 5e-3, channels)
    offset = x.mean(axis=0) if seed % 2 else np.zeros(channels)
    sos: np.ndarray = (ENVELOPE if envelope else BANDPASS).astype(precision)
    expected = _scipy(sos, x, offset, rectify)
    out = np.full_like(x, np.nan)
    zero_phase(sos, x, out, offset=offset, rectify=rectify, threads=threads, lanes=lanes)
    scale = np.abs(expected).max()
    tol = 1e-6 if precision == np.float32 else 1e-12
    assert np.abs(out - expected).max() <= tol * scale


def test_in_place_equals_out_of_place() -> None:
    x = np.random.default_rng(1).standard_normal((5000, 16))
    out = np.empty_like(x)
    zero_phase(ENVELOPE, x, out, rectify=True)
    same = x.copy()
    zero_phase(ENVELOPE, same, same, rectify=True)
    np.testing.assert_array_equal(same, out)
    np.testing.assert_array_equal(out[:, 3], signal.sosfiltfilt(ENVELOPE, np.abs(x[:, 3])))


def test_padding_is_sosfiltfilts() -> None:
    assert pad_length(BANDPASS) == 33  # 5 sections: 3 x (2 x 5 + 1)
    assert pad_length(ENVELOPE) == 15


@pytest.mark.parametrize(("src", "lanes", "message"), [
    (np.zeros((30, 2)), 8, "needs more than 33"),
    (np.zeros((100, 2), dtype=np.float32), 8, "float64"),
    (np.zeros((100, 4))[:, ::2], 8, "C-ordered"),
    (np.zeros((100, 2)), 0, "lanes must be positive"),
])
def test_refuses_what_it_cannot_filter(src: np.ndarray, lanes: int, message: str) -> None:
    with pytest.raises((ValueError, TypeError), match=message):
        zero_phase(BANDPASS, src, np.zeros(src.shape), lanes=lanes)


@settings(max_examples=15, deadline=None)
@given(channels=st.integers(1, 19), seed=st.integers(0, 2**16),
       cuts=st.lists(st.integers(0, 1500), max_size=6))
def test_causal_envelope_is_sosfilt_twice_whatever_the_blocks(channels: int, seed: int,
                                                              cuts: list[int]) -> None:
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((1500, channels)) * 1e-4 + rng.uniform(-5e-3, 5e-3, channels)
    zi = signal.sosfilt_zi(BANDPASS)[:, :, None] * x[0][None, None, :]
    y, _ = signal.sosfilt(BANDPASS, x, axis=0, zi=zi)
    expected = signal.sosfilt(ENVELOPE, np.abs(y), axis=0)
    live = CausalEnvelope(BANDPASS, ENVELOPE, channels)
    bounds = [0, *sorted(cuts), 1500]
    got = np.vstack([live.push(x[a:b]) for a, b in zip(bounds, bounds[1:], strict=False)])
    np.testing.assert_array_equal(got, expected)


def test_causal_envelope_refuses_another_channel_count() -> None:
    with pytest.raises(ValueError, match="at least one channel"):
        CausalEnvelope(BANDPASS, ENVELOPE, 0)
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        CausalEnvelope(BANDPASS, ENVELOPE, 3).push(np.zeros((10, 2)))
