"""Per-lift outcomes from a (normalised) envelope: peak, mean and integrated EMG per
channel over the lift and over each of its phases, and the envelope over the normalised
lift cycle (101 points, 0 to 100 %).

Integrated EMG (iEMG) here is the trapezoid integral of the *envelope* over the window,
in the envelope's unit times seconds. The envelope's low-pass has a DC gain of one, so
over a window much longer than the low-pass's time constant (1/6 Hz) this equals the
integral of the rectified band-passed signal, the classic definition, without its
sample-to-sample noise; near the window's edges they differ by the smoothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.emg.normalisation import Window, check_window
from controller.emg.processing import FloatArray

CYCLE_POINTS = 101


@dataclass(frozen=True, slots=True)
class WindowOutcome:
    """Per channel: the envelope's peak and mean and its integral (iEMG) over a window."""

    peak: tuple[float, ...]
    mean: tuple[float, ...]
    iemg: tuple[float, ...]
    duration_s: float

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports."""
        return {"peak": list(self.peak), "mean": list(self.mean), "iemg": list(self.iemg),
                "duration_s": self.duration_s}


@dataclass(frozen=True, slots=True)
class LiftOutcome:
    """One lift's outcomes: the whole lift, each phase, and the normalised cycle
    (CYCLE_POINTS x n_channels, 0 to 100 % of the lift)."""

    lift: WindowOutcome
    phases: Mapping[str, WindowOutcome] = field(default_factory=dict)
    cycle: FloatArray = field(default_factory=lambda: np.empty((0, 0)))

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports (the cycle as rows of channels)."""
        return {"lift": self.lift.to_dict(),
                "phases": {k: v.to_dict() for k, v in self.phases.items()},
                "cycle": self.cycle.tolist()}


def _check_envelope(envelope: NDArray[Any]) -> FloatArray:
    env = np.asarray(envelope, dtype=np.float64)
    if env.ndim != 2:
        raise ValueError(f"envelope must be (n_samples, n_channels), got shape {env.shape}")
    if not np.isfinite(env).all():
        raise ValueError("envelope has NaN or infinite samples")
    return env


def window_outcome(envelope: NDArray[Any], fs: float, window: Window) -> WindowOutcome:
    """Peak, mean and iEMG per channel over `window` (sample indices, stop excluded)."""
    return _window_outcome(_check_envelope(envelope), fs, window)


def _window_outcome(env: FloatArray, fs: float, window: Window) -> WindowOutcome:
    """`window_outcome` of an envelope `_check_envelope` has passed."""
    if not fs > 0:
        raise ValueError(f"fs must be positive, got {fs}")
    start, stop = check_window(window, env.shape[0])
    seg = env[start:stop]
    iemg = (np.atleast_1d(np.trapezoid(seg, dx=1.0 / fs, axis=0)) if len(seg) > 1
            else np.zeros(env.shape[1]))
    return WindowOutcome(tuple(float(v) for v in seg.max(axis=0)),
                         tuple(float(v) for v in seg.mean(axis=0)),
                         tuple(float(v) for v in iemg), (stop - start) / fs)


def normalised_cycle(envelope: NDArray[Any], window: Window,
                     n_points: int = CYCLE_POINTS) -> FloatArray:
    """The envelope over `window` resampled (linear interpolation) to `n_points` equally
    spaced points from the first to the last sample of the window (0 to 100 %)."""
    return _normalised_cycle(_check_envelope(envelope), window, n_points)


def _normalised_cycle(env: FloatArray, window: Window, n_points: int) -> FloatArray:
    """`normalised_cycle` of an envelope `_check_envelope` has passed."""
    start, stop = check_window(window, env.shape[0])
    if stop - start < 2:
        raise ValueError(f"window {window} needs at least 2 samples for a cycle")
    seg = env[start:stop]
    src = np.linspace(0.0, 1.0, len(seg))
    dst = np.linspace(0.0, 1.0, n_points)
    return np.column_stack([np.interp(dst, src, seg[:, c]) for c in range(env.shape[1])])


def lift_outcome(envelope: NDArray[Any], fs: float, lift: Window,
                 phases: Mapping[str, Window] | None = None) -> LiftOutcome:
    """Outcomes of one lift; each phase window must lie inside the lift. The envelope
    is checked once for all of them (the check reads every sample of it)."""
    phases = phases or {}
    start, stop = check_window(lift, np.asarray(envelope).shape[0])
    for name, (p0, p1) in phases.items():
        if not start <= p0 < p1 <= stop:
            raise ValueError(f"phase {name!r} {(p0, p1)} is not inside the lift {lift}")
    env = _check_envelope(envelope)
    return LiftOutcome(_window_outcome(env, fs, lift),
                       {k: _window_outcome(env, fs, w) for k, w in phases.items()},
                       _normalised_cycle(env, lift, CYCLE_POINTS))
