"""Amplitude normalisation of EMG envelopes and its references.

The methods are those of the CEDE consensus matrix (Besomi et al. 2020): "mvc" divides
by the envelope's maximum during maximum voluntary contractions of the same muscle,
"task_peak" by the peak and "task_mean" by the mean of the envelope over the task's own
windows, "none" keeps volts. The method is stated with every result.

MVC reference: the maximum over the MVC windows of the envelope's moving average over
`window_s` (0.5 s by default, `EmgProcessing.mvc_window_s`): a short average rather than
a single sample, so one spike does not set the reference. The same average over the task
windows tells when task activity exceeds the MVC, which means the MVC was not maximal
(`exceeds_reference`): those results are flagged, not hidden.

Windows are sample index pairs `(start, stop)`, stop excluded, into the envelope.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.emg.processing import NORMALISATION_METHODS, FloatArray, NormalisationMethod

Window = tuple[int, int]

UNITS: dict[str, str] = {
    "mvc": "fraction of MVC",
    "task_peak": "fraction of task peak",
    "task_mean": "fraction of task mean",
    "none": "V",
}


def check_window(window: Window, n_samples: int) -> Window:
    """`window` as ints if it is a non-empty (start, stop) inside `n_samples`, else an error."""
    start, stop = int(window[0]), int(window[1])
    if not 0 <= start < stop <= n_samples:
        raise ValueError(f"window {window} is not a non-empty (start, stop) within "
                         f"0..{n_samples}")
    return start, stop


def _check_envelope(envelope: NDArray[Any]) -> FloatArray:
    env = np.asarray(envelope, dtype=np.float64)
    if env.ndim != 2:
        raise ValueError(f"envelope must be (n_samples, n_channels), got shape {env.shape}")
    return env


def moving_average_max(envelope: NDArray[Any], fs: float, windows: Sequence[Window],
                       window_s: float) -> FloatArray:
    """Per channel, the largest `window_s` moving average of the envelope inside any of
    `windows` (each must hold at least one full average)."""
    env = _check_envelope(envelope)
    width = max(1, round(window_s * fs))
    if not windows:
        raise ValueError("need at least one window")
    best = np.full(env.shape[1], -np.inf)
    for w in windows:
        start, stop = check_window(w, env.shape[0])
        if stop - start < width:
            raise ValueError(f"window {w} has {stop - start} samples, shorter than the "
                             f"{window_s} s moving average ({width} samples)")
        csum = np.cumsum(np.vstack([np.zeros((1, env.shape[1])), env[start:stop]]), axis=0)
        means = (csum[width:] - csum[:-width]) / width
        best = np.maximum(best, means.max(axis=0))
    return best


def mvc_reference(envelope: NDArray[Any], fs: float, mvc_windows: Sequence[Window],
                  window_s: float = 0.5) -> FloatArray:
    """Per channel MVC reference from the envelope of MVC trials (volts)."""
    return moving_average_max(envelope, fs, mvc_windows, window_s)


def task_reference(envelope: NDArray[Any], task_windows: Sequence[Window],
                   method: NormalisationMethod) -> FloatArray:
    """Per channel task-peak (largest sample) or task-mean (mean of all window samples)."""
    env = _check_envelope(envelope)
    if not task_windows:
        raise ValueError("need at least one task window")
    parts = [env[slice(*check_window(w, env.shape[0]))] for w in task_windows]
    if method == "task_peak":
        return np.max([p.max(axis=0) for p in parts], axis=0)
    if method == "task_mean":
        return np.concatenate(parts, axis=0).mean(axis=0)
    raise ValueError(f"task_reference needs 'task_peak' or 'task_mean', got {method!r}")


@dataclass(frozen=True, slots=True)
class Reference:
    """What envelopes are divided by, per channel, and by which method."""

    method: NormalisationMethod
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.method not in NORMALISATION_METHODS:
            raise ValueError(f"unknown normalisation {self.method!r}; use one of "
                             f"{NORMALISATION_METHODS}")
        bad = [i for i, v in enumerate(self.values) if not (np.isfinite(v) and v > 0)]
        if bad:
            raise ValueError(f"normalisation reference must be positive and finite; channels "
                             f"{bad} are not ({[self.values[i] for i in bad]})")

    @property
    def unit(self) -> str:
        """The unit of a normalised envelope."""
        return UNITS[self.method]

    @classmethod
    def none(cls, n_channels: int) -> Reference:
        """No normalisation: divide by one, results stay in volts."""
        return cls("none", (1.0,) * n_channels)

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports."""
        return {"method": self.method, "unit": self.unit, "values": list(self.values)}


def normalise(envelope: NDArray[Any], reference: Reference) -> FloatArray:
    """The envelope divided by the reference, channel by channel."""
    env = _check_envelope(envelope)
    if env.shape[1] != len(reference.values):
        raise ValueError(f"envelope has {env.shape[1]} channels, reference "
                         f"{len(reference.values)}")
    return env / np.asarray(reference.values)


@dataclass(frozen=True, slots=True)
class ExceedsReference:
    """Task activity against the MVC per channel: the ratio of the task's largest moving
    average to the MVC reference, and whether it is above one (a submaximal MVC)."""

    ratio: tuple[float, ...]
    exceeds: tuple[bool, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports."""
        return {"ratio": list(self.ratio), "exceeds": list(self.exceeds)}


def exceeds_reference(envelope: NDArray[Any], fs: float, task_windows: Sequence[Window],
                      mvc: Reference, window_s: float = 0.5) -> ExceedsReference:
    """Flag channels whose task activity (same moving average as the MVC) exceeds the MVC.

    Windows shorter than the average are measured over their full length instead.
    """
    env = _check_envelope(envelope)
    width = max(1, round(window_s * fs))
    peaks = np.full(env.shape[1], -np.inf)
    for w in task_windows:
        start, stop = check_window(w, env.shape[0])
        span = min(width, stop - start)
        peaks = np.maximum(peaks, moving_average_max(env, fs, [(start, stop)], span / fs))
    ratio = peaks / np.asarray(mvc.values)
    return ExceedsReference(tuple(float(r) for r in ratio), tuple(bool(r > 1.0) for r in ratio))
