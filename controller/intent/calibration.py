"""E-UMC calibration: map the wearer's rest posture onto the models' mean at `s = 0`.

The wearer stands still for a few seconds (docs/controller-design.md, "E-UMC and PEC"). The mean of
each raw hip angle over that period, minus the models' mean at `s = 0`, becomes an
offset, so `q = q_raw - offset = q_raw - rest_mean + model_mean_at_s0`. This removes
offsets from the fit of the device on the waist and from donning and doffing.

A calibration whose standard deviation (population, ddof = 0) exceeds a limit
(default 1 degree) is rejected: the wearer was moving and the mean is not a rest
posture. One whose offset exceeds 60 degrees is rejected too: the wearer was still,
but not standing (held at the bottom of a squat, say).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from controller.config import CALIBRATION_MAX_RAD

#: Default limit on the standard deviation of a still period, rad (1 degree).
MAX_STD = math.radians(1.0)
#: Default minimum length of the still period: 1 s at 100 Hz.
MIN_SAMPLES = 100
#: Largest offset, rad, that still maps a standing posture (`controller.config`).
OFFSET_MAX = CALIBRATION_MAX_RAD


class CalibrationError(ValueError):
    """The recorded period cannot serve as a calibration (too short, NaN, or moving)."""


@dataclass(frozen=True, slots=True)
class Calibration:
    """Per-side offsets (rad) subtracted from raw hip angles."""

    offset_left: float
    offset_right: float

    def apply(self, q_raw_left: float, q_raw_right: float) -> tuple[float, float]:
        """Calibrated (left, right) hip angles."""
        return q_raw_left - self.offset_left, q_raw_right - self.offset_right


#: No correction: raw angles pass through unchanged (UMC and PEC, or before calibration).
IDENTITY = Calibration(0.0, 0.0)


def calibrate(
    angles: npt.ArrayLike,
    model_start_mean: npt.ArrayLike,
    max_std: float = MAX_STD,
    min_samples: int = MIN_SAMPLES,
) -> Calibration:
    """Offsets from a still period.

    Args:
        angles: (K, 2) raw (left, right) hip angles, rad, K >= min_samples.
        model_start_mean: (2,) models' mean (left, right) at `s = 0`, rad.
        max_std: Largest standard deviation of either hip that still counts as still.
        min_samples: Fewest samples accepted.

    Raises:
        CalibrationError: too few samples, NaN or inf, or a standard deviation above
            `max_std` (the message gives both hips' values in degrees), or an offset
            beyond `OFFSET_MAX` (not a standing posture).
    """
    if not (math.isfinite(max_std) and max_std > 0):
        raise CalibrationError(f"max_std must be a positive number, got {max_std!r}")
    if min_samples < 2:
        raise CalibrationError(f"min_samples must be at least 2, got {min_samples!r}")
    a = np.asarray(angles, dtype=np.float64)
    target = np.asarray(model_start_mean, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2:
        raise CalibrationError(f"angles must have shape (K, 2), got {a.shape}")
    if target.shape != (2,) or not np.all(np.isfinite(target)):
        raise CalibrationError(f"model_start_mean must be 2 finite numbers, got {target!r}")
    if a.shape[0] < min_samples:
        raise CalibrationError(
            f"calibration needs at least {min_samples} samples, got {a.shape[0]}"
        )
    if not np.all(np.isfinite(a)):
        n_bad = int(np.count_nonzero(~np.isfinite(a).all(axis=1)))
        raise CalibrationError(
            f"calibration period has NaN or inf in {n_bad} of {len(a)} samples"
        )
    std = a.std(axis=0)
    if np.any(std > max_std):
        raise CalibrationError(
            "wearer was not still: hip angle std "
            f"left {math.degrees(std[0]):.2f} deg, right {math.degrees(std[1]):.2f} deg "
            f"(limit {math.degrees(max_std):.2f} deg)"
        )
    offset = a.mean(axis=0) - target
    if np.any(np.abs(offset) > OFFSET_MAX):
        raise CalibrationError(
            "wearer was not standing: offsets left "
            f"{math.degrees(offset[0]):.1f} deg, right {math.degrees(offset[1]):.1f} deg "
            f"from the models' start posture (a standing posture is within "
            f"+-{math.degrees(OFFSET_MAX):.0f} deg)"
        )
    return Calibration(offset_left=float(offset[0]), offset_right=float(offset[1]))


class StillnessMonitor:
    """Live standard deviation of both hips over a sliding window, for the console.

    `push` is O(1); the standard deviation is computed exactly (two-pass, no running
    sums that drift) only when asked for, at display rate.
    """

    def __init__(self, window: int = MIN_SAMPLES, max_std: float = MAX_STD) -> None:
        """Args: window length in samples (>= 2), max_std limit in rad."""
        if window < 2:
            raise ValueError(f"window must be >= 2 samples, got {window}")
        if not (math.isfinite(max_std) and max_std > 0):
            raise ValueError(f"max_std must be a positive number, got {max_std!r}")
        self.window = window
        self.max_std = max_std
        self._buf = np.empty((window, 2), dtype=np.float64)
        self._pos = 0
        self._count = 0

    def push(self, q_left: float, q_right: float) -> None:
        """Add one raw sample (NaN is kept and makes the window not still)."""
        self._buf[self._pos, 0] = q_left
        self._buf[self._pos, 1] = q_right
        self._pos = (self._pos + 1) % self.window
        self._count = min(self._count + 1, self.window)

    def reset(self) -> None:
        """Forget all samples."""
        self._pos = 0
        self._count = 0

    @property
    def full(self) -> bool:
        """True once the window holds `window` samples."""
        return self._count == self.window

    def std(self) -> tuple[float, float]:
        """(left, right) standard deviation over the window, rad; NaN if under 2 samples."""
        if self._count < 2:
            return math.nan, math.nan
        s = self._buf[: self._count].std(axis=0)
        return float(s[0]), float(s[1])

    def is_still(self) -> bool:
        """Full window, no NaN, and both deviations within `max_std`."""
        if not self.full:
            return False
        sl, sr = self.std()
        return sl <= self.max_std and sr <= self.max_std

    def samples(self) -> npt.NDArray[np.float64]:
        """The window's samples, oldest first (a copy), ready for `calibrate`."""
        if self._count < self.window:
            return self._buf[: self._count].copy()
        return np.roll(self._buf, -self._pos, axis=0)
