"""Hardware bring-up arithmetic: encoder zero, mounting direction and the cam-to-output
offset, from raw counts captured with the solenoids off.

Pure functions on count arrays, so the server's steps and the tests share one
definition and real hardware, the C device and the simulator are judged alike. Counts
wrap at one turn (`controller.lowlevel.encoders`); every difference here is taken modulo 16384
into half a turn either side, so a zero near the wrap point averages correctly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from controller.device.base import ENCODER_COUNTS, Status
from controller.lowlevel.encoders import RAD_PER_COUNT, EncoderLayout

DEG_PER_COUNT = math.degrees(RAD_PER_COUNT)
#: Standing still: each encoder's spread at most this (deg RMS). The AS5048A's noise is
#: at most 0.06 deg RMS (datasheet); a standing person sways a few tenths of a degree.
#: Assumption: 0.5 deg separates "still" from "moving" with margin on both sides.
STILL_STD_DEG = 0.5
#: A flexion for the direction step must move the output link at least this far; the
#: other side must stay below half of it. Assumption: 10 deg is an easy, deliberate
#: flexion, far above noise and sway.
MIN_FLEXION_DEG = 10.0
#: After the cam offset, |alpha| of an unlocked side stays within this. Each encoder
#: may be off by up to 0.8 deg (non-linearity, datasheet), so output minus cam by 1.6;
#: 2 deg adds the noise.
ALPHA_TOLERANCE_DEG = 2.0
INDEX = {"left": (0, 1), "right": (2, 3)}  # (output, cam) encoder of each side
_HALF = ENCODER_COUNTS // 2
IntArray = npt.NDArray[np.int64]


class BringupError(ValueError):
    """A capture that does not allow the step (moving, faults, the wrong side moved)."""


def wrap(d: npt.ArrayLike) -> IntArray:
    """Count differences into [-8192, 8192)."""
    return (np.asarray(d, dtype=np.int64) + _HALF) % ENCODER_COUNTS - _HALF


def circular_mean(counts: npt.ArrayLike) -> tuple[int, float]:
    """Mean count (rounded, 0..16383) and its spread in counts, unwrapped around the
    first value."""
    c = np.asarray(counts, dtype=np.int64)
    d = wrap(c - c[0])
    return round(float(c[0] + d.mean())) % ENCODER_COUNTS, float(d.std())


def counts_of(samples: npt.ArrayLike) -> tuple[IntArray, IntArray]:
    """(counts (N, 4), status (N,)) of raw samples (rows: arrival s, seq, t, four
    counts, status: `backend.worker.messages.RawSample`)."""
    a = np.asarray(samples, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 8 or a.shape[0] == 0:
        raise BringupError("no samples were captured")
    return a[:, 3:7].astype(np.int64), a[:, 7].astype(np.int64)


def _usable(status: IntArray) -> None:
    bad = int(np.bitwise_or.reduce(status))
    for flag, what in ((Status.ENCODER_FAULT, "an encoder fault"),
                       (Status.SUPPLY_FAULT, "a supply fault"),
                       (Status.LOCKED_LEFT | Status.LOCKED_RIGHT, "a pawl engaged")):
        if bad & int(flag):
            raise BringupError(f"the device reported {what} during the capture")


@dataclass(frozen=True, slots=True)
class ZeroResult:
    """Counts at the standing posture (the new zero of each encoder) and their spread."""

    offsets: tuple[int, int, int, int]
    std_deg: tuple[float, float, float, float]


def zero(samples: npt.ArrayLike, max_std_deg: float = STILL_STD_DEG) -> ZeroResult:
    """Each encoder's mean count over a still capture; refuses a capture that moved."""
    counts, status = counts_of(samples)
    _usable(status)
    means, stds = zip(*(circular_mean(counts[:, i]) for i in range(4)), strict=True)
    std_deg = tuple(s * DEG_PER_COUNT for s in stds)
    moving = [i for i, s in enumerate(std_deg) if s > max_std_deg]
    if moving:
        names = ", ".join(ENCODER_NAMES[i] for i in moving)
        worst = max(std_deg[i] for i in moving)
        raise BringupError(f"not still: {names} moved ({worst:.2f} deg RMS, at most "
                           f"{max_std_deg:g}); stand still and repeat")
    return ZeroResult(tuple(means), std_deg)


ENCODER_NAMES = ("left output", "left cam", "right output", "right cam")


@dataclass(frozen=True, slots=True)
class DirectionResult:
    """Mounting direction of a side's two encoders (+1: counts rise with flexion) and
    how far each output link moved (deg, the largest excursion from the start)."""

    side: str
    output_direction: int
    cam_direction: int
    moved_deg: float
    other_moved_deg: float


def _excursion(counts: IntArray, reference: int | None) -> int:
    """The signed count excursion of largest size from `reference` (None: the first
    sample)."""
    d = wrap(counts - (counts[0] if reference is None else reference))
    return int(d[int(np.argmax(np.abs(d)))])


def direction(samples: npt.ArrayLike, side: str,
              min_flexion_deg: float = MIN_FLEXION_DEG,
              reference: tuple[int, int, int, int] | None = None) -> DirectionResult:
    """The sign of each encoder of `side` from a capture in which that hip flexed.

    Excursions are measured from `reference`, the standing counts of the zero step
    (flexion moves away from standing whenever the capture starts), else from the
    first sample (then the capture must start standing)."""
    ref = (None, None, None, None) if reference is None else reference
    if side not in INDEX:
        raise BringupError(f"side must be 'left' or 'right', got {side!r}")
    counts, status = counts_of(samples)
    _usable(status)
    other = "right" if side == "left" else "left"
    (out, cam), (other_out, _) = INDEX[side], INDEX[other]
    moved = _excursion(counts[:, out], ref[out]) * DEG_PER_COUNT
    cam_moved = _excursion(counts[:, cam], ref[cam]) * DEG_PER_COUNT
    other_moved = _excursion(counts[:, other_out], ref[other_out]) * DEG_PER_COUNT
    if abs(moved) < min_flexion_deg:
        if abs(other_moved) >= min_flexion_deg:
            raise BringupError(f"the {other} hip moved ({abs(other_moved):.1f} deg), not the "
                               f"{side}: flex the {side} hip (or the encoder cables are "
                               "swapped between the sides)")
        raise BringupError(f"the {side} hip moved only {abs(moved):.1f} deg: flex it by at "
                           f"least {min_flexion_deg:g} deg during the capture")
    if abs(other_moved) >= min_flexion_deg / 2:
        raise BringupError(f"both hips moved ({abs(moved):.1f} deg {side}, "
                           f"{abs(other_moved):.1f} deg {other}): keep the {other} hip still")
    if abs(cam_moved) < abs(moved) / 2:
        raise BringupError(f"the {side} cam link did not follow the output link "
                           f"({abs(cam_moved):.1f} of {abs(moved):.1f} deg): is that side "
                           "locked, or its cam encoder loose?")
    return DirectionResult(side, 1 if moved > 0 else -1, 1 if cam_moved > 0 else -1,
                           abs(moved), abs(other_moved))


@dataclass(frozen=True, slots=True)
class CamOffsetResult:
    """Cam encoder zeros that make `alpha = 0` while unlocked, the cam-to-output offset
    (cam zero minus output zero, counts in [-8192, 8192)) and the residual alpha."""

    cam_offsets: tuple[int, int]  # left, right
    cam_output_offsets: tuple[int, int]
    alpha_max_deg: tuple[float, float]
    alpha_std_deg: tuple[float, float]


def cam_offset(samples: npt.ArrayLike, layout: EncoderLayout,
               tolerance_deg: float = ALPHA_TOLERANCE_DEG) -> CamOffsetResult:
    """Cam zeros from an unlocked capture, given the output zeros and all directions in
    `layout`; refuses a capture in which |alpha| would still exceed `tolerance_deg`."""
    counts, status = counts_of(samples)
    _usable(status)
    cams: list[int] = []
    rel: list[int] = []
    amax: list[float] = []
    astd: list[float] = []
    for side in ("left", "right"):
        out, cam = INDEX[side]
        d_out, d_cam = layout.directions[out], layout.directions[cam]
        # Output angle of each sample in counts; the cam zero that reads the same angle.
        steps = d_out * wrap(counts[:, out] - layout.offsets[out])
        candidates = (counts[:, cam] - d_cam * steps) % ENCODER_COUNTS
        off, _ = circular_mean(candidates)
        alpha = d_cam * wrap(counts[:, cam] - off) - steps  # cam minus output, counts
        alpha_deg = -alpha * DEG_PER_COUNT  # alpha = output - cam
        worst = float(np.abs(alpha_deg).max())
        if worst > tolerance_deg:
            raise BringupError(f"{side}: alpha reaches {worst:.2f} deg with the best cam "
                               f"offset (at most {tolerance_deg:g}): the cam link does not "
                               "follow the output link; is that side locked?")
        cams.append(off)
        rel.append(int(wrap(off - layout.offsets[out])))
        amax.append(worst)
        astd.append(float(alpha_deg.std()))
    return CamOffsetResult((cams[0], cams[1]), (rel[0], rel[1]), (amax[0], amax[1]),
                           (astd[0], astd[1]))
