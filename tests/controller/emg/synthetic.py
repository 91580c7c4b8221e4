"""Synthetic EMG for the tests: band-limited Gaussian noise with a known spread."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def band_noise(n: int, fs: float, band: tuple[float, float], sigma: float,
               seed: int = 0, channels: int = 1) -> NDArray[np.float64]:
    """Gaussian noise with an ideal (FFT) pass band, scaled to standard deviation `sigma`."""
    rng = np.random.default_rng(seed)
    spec = np.fft.rfft(rng.normal(size=(n, channels)), axis=0)
    f = np.fft.rfftfreq(n, 1.0 / fs)
    spec[(f < band[0]) | (f > band[1])] = 0.0
    x = np.fft.irfft(spec, n=n, axis=0)
    return np.asarray(sigma * x / x.std(axis=0), dtype=np.float64)


