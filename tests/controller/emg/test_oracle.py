"""The chain against an independent implementation: pyemgpipeline 1.0.0's processors
(DC offset removal, Butterworth band-pass with filtfilt, full-wave rectification,
Butterworth linear envelope with filtfilt) with the same parameters.

pyemgpipeline's `bf_order`/`le_order` are the *effective* order after forward-backward
filtering and it designs with N = order / 2, so our N = 4 is its order 8. It filters in
transfer-function (b, a) form with `filtfilt`, ours in second-order sections with
`sosfiltfilt`; with these designs both pad by the same 27 (band-pass) and 15 (envelope)
samples with an odd extension, so the only residual is the rounding of the two forms,
measured at about 3e-9 of the mean envelope. The tolerance, 1e-6, leaves room for other
platforms' BLAS/LAPACK in the (b, a) design.
"""

from __future__ import annotations

import numpy as np
import pytest
from pyemgpipeline.processors import (
    BandpassFilter,
    DCOffsetRemover,
    FullWaveRectifier,
    LinearEnvelope,
)

from controller.emg.processing import EmgProcessing, process
from tests.controller.emg.synthetic import band_noise

TOLERANCE = 1e-6


def _oracle(raw: np.ndarray, fs: float, s: EmgProcessing) -> np.ndarray:
    y = DCOffsetRemover().apply(raw)
    y = BandpassFilter(fs, 2 * s.bandpass_order, s.highpass_hz, s.lowpass_hz).apply(y)
    y = FullWaveRectifier().apply(y)
    return np.asarray(LinearEnvelope(fs, 2 * s.envelope_order, s.envelope_hz).apply(y))


@pytest.mark.parametrize(("fs", "settings"), [
    (2000.0, EmgProcessing(precision="float64")),
    (2000.0, EmgProcessing(highpass_hz=30.0, envelope_hz=4.0, precision="float64")),
    (1000.0, EmgProcessing(lowpass_hz=400.0, bandpass_order=2, envelope_order=2,
                           envelope_hz=10.0, precision="float64")),
])
def test_envelope_matches_pyemgpipeline(fs: float, settings: EmgProcessing) -> None:
    n = int(12 * fs)
    t = np.arange(n) / fs
    activation = 0.3 + 0.7 * np.sin(np.pi * t / 3.0) ** 2  # lifts every 3 s
    raw = band_noise(n, fs, (20.0, 400.0), 1e-4, seed=11, channels=3) * activation[:, None]
    raw += np.array([3e-3, -1e-3, 0.0])  # electrode offsets
    ours = process(raw, fs, settings)
    theirs = _oracle(raw, fs, settings)
    assert np.abs(ours - theirs).max() < TOLERANCE * theirs.mean()


def test_default_float32_chain_matches_pyemgpipeline_within_its_precision() -> None:
    fs = 2000.0
    raw = band_noise(int(10 * fs), fs, (20.0, 400.0), 1e-4, seed=12, channels=2) + 2e-3
    theirs = _oracle(raw, fs, EmgProcessing())
    ours = process(raw, fs, EmgProcessing())
    assert np.abs(ours - theirs).max() < 2e-3 * theirs.mean()
