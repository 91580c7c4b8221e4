"""The plausibility check of a decoded sample, compiled into every controller's tick.

The bounds and their reasons are in `controller.lowlevel.plausibility`; this module applies them
against the `REFERENCE` record of the last accepted samples.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from controller.config import ControllerConfig
from controller.intent.kalman import HipVelocityFilter, kalman_step
from controller.kernel.records import (
    FloatArray,
    IntArray,
    RecordArray,
    new_reference,
    settings_record,
)
from controller.lowlevel.plausibility import Q_RANGE
from controller.tick_record import Plausibility

JUMP = int(Plausibility.JUMP)
VELOCITY = int(Plausibility.VELOCITY)
REPEATED = int(Plausibility.REPEATED)
TIME_BACKWARDS = int(Plausibility.TIME_BACKWARDS)
TOO_EARLY = int(Plausibility.TOO_EARLY)
RANGE = int(Plausibility.RANGE)
RESYNC = int(Plausibility.RESYNC)
ACCELERATION = int(Plausibility.ACCELERATION)
#: The bits after which the device is taken as restarted (held locks are dropped).
PRESYNC_OR_BACK = TIME_BACKWARDS | RESYNC


@njit(cache=True, nogil=True)
def check_sample(  # type: ignore[no-untyped-def]
    s, ref, kal_st: FloatArray, kal_k: FloatArray, win_pc: IntArray,
    t: float, q_l: float, q_r: float, a_l: float, a_r: float,
) -> int:
    """The `Plausibility` bits of a well-formed sample (0: plausible), updating `ref`
    (a `REFERENCE` record) under the bounds of `s` (a `SETTINGS` record).

    Device time is checked against the last sample seen (repeated, backwards) and the
    last accepted one (too early); angles against the last accepted one (jump) and
    against where the last two accepted ones say the hip is heading (acceleration), so
    a single glitch costs one tick and the next good sample is compared with the good
    ones before it. Time going backwards is a new device: the filters and the window restart
    and the sample becomes the new reference (flagged). A silence longer than the
    resync time restarts them too. An accepted sample more than one period after the
    previous accepted one (samples skipped here or lost on the link) first advances the
    velocity filter by the missing periods, so it does not read the longer step as a
    faster hip.
    """
    bits = 0
    if not (s.alpha_lo <= a_l <= s.alpha_hi and s.alpha_lo <= a_r <= s.alpha_hi):
        bits |= RANGE
    seen = ref.t_seen
    first = ref.have == 0
    if not first and t == seen:
        return bits | REPEATED  # nothing else changes: the same sample again
    ref.t_seen = t
    if not first and t < seen:
        kal_st[0] = 0.0  # the filter re-initialises at its next sample
        win_pc[0] = 0
        win_pc[1] = 0
        ref.have = 0
        return bits | TIME_BACKWARDS
    if bits:
        return bits
    if first:
        ref.have = 1
        ref.have_velocity = 0
        ref.t = t
        ref.q_left = q_l
        ref.q_right = q_r
        return 0
    dt = t - ref.t
    if dt < s.min_interval:
        return TOO_EARLY
    if dt > s.resync:
        kal_st[0] = 0.0
        win_pc[0] = 0
        win_pc[1] = 0
        ref.have_velocity = 0
        ref.t = t
        ref.q_left = q_l
        ref.q_right = q_r
        return RESYNC
    # The bounds grow with the time since the last accepted sample, but only up to two
    # periods: a reading that stays off (an encoder that jumped and stayed) is not let
    # in gradually, as a fast movement would be read from it; it waits for the resync.
    db = min(dt, 2.0 * kal_k[0])
    bound = s.velocity_max * db + s.angle_noise
    if abs(q_l - ref.q_left) > bound or abs(q_r - ref.q_right) > bound:
        return JUMP
    if ref.have_velocity != 0:
        # The velocity is a backward difference (half a period old), so the hip can be
        # a * dt^2 off its course, not a * dt^2 / 2.
        reach = s.accel_max * db * db + s.angle_noise
        if (abs(q_l - ref.q_left - ref.v_left * dt) > reach
                or abs(q_r - ref.q_right - ref.v_right * dt) > reach):
            return ACCELERATION
    for _ in range(round(dt / kal_k[0]) - 1):  # kal_k[0]: the filter's period
        kalman_step(kal_st, kal_k, math.nan, math.nan)  # predict only
    ref.v_left = (q_l - ref.q_left) / dt
    ref.v_right = (q_r - ref.q_right) / dt
    ref.have_velocity = 1
    ref.t = t
    ref.q_left = q_l
    ref.q_right = q_r
    return 0


@njit(cache=True, nogil=True)
def _check_one(  # type: ignore[no-untyped-def]
    settings, reference, kal_st, kal_k, win_pc, t, q_l, q_r, a_l, a_r,
) -> int:
    return check_sample(settings[0], reference[0], kal_st, kal_k, win_pc, t, q_l, q_r, a_l,
                        a_r)


class SampleChecker:
    """`check_sample` on its own, for a controller that decides nothing (recording mode):
    its ticks carry the same plausibility flags as every other controller's."""

    def __init__(self) -> None:
        c = ControllerConfig()
        self.settings: RecordArray = settings_record(c, 1, 1, -1)
        self.reference: RecordArray = new_reference()
        # The check restarts or advances a velocity filter and a window; here they only
        # keep `check_sample`'s signature (nothing reads them).
        self._filter = HipVelocityFilter()
        self._window = np.zeros(2, dtype=np.int64)

    def reset(self) -> None:
        """Forget the reference."""
        self.reference[:] = new_reference()

    def check(self, t: float, q_l: float, q_r: float, a_l: float, a_r: float) -> int:
        """The `Plausibility` bits of one decoded sample (0: plausible)."""
        if not (Q_RANGE[0] <= q_l <= Q_RANGE[1] and Q_RANGE[0] <= q_r <= Q_RANGE[1]):
            return RANGE
        return int(_check_one(self.settings, self.reference, self._filter.state,
                              self._filter.constants, self._window, t, q_l, q_r, a_l, a_r))
