"""The compiled control tick: one numba function per 100 Hz tick, live and in replay.

`tick` does what `PipelineController.step` promises (see `controller.pipeline`): check
the sample, counts to angles, calibration offsets, Kalman velocities and the trigger,
the observation window, the decision of the UMC, E-UMC or PEC (an integer mode), the
0.3 s lock hold, the mechanism state and the torque estimate. It writes one row of
numbers (`OUT_FIELDS`, the numeric `TickRecord` fields from `q_raw_left` to
`plausibility`)
and keeps all state in preallocated arrays owned by a `TickCore`.

Why compiled, and why one function: replaying a 10-minute recording must take well
under a second, and replay must run the very code of the live loop. The live path
(`PipelineController.step`) calls `tick` once per sample from Python; the batch replay
(`controller.replay.replay_kernel`) calls the same `tick` in a compiled loop, with the exoskeleton's
mechanism (`controller.sim.plant.plant_step`, the simulator's own) between the lock
command of one tick and the sample of the next. Every building block is the shared
compiled kernel of its module (window, DTW bank, likelihoods, decision, Kalman filter,
hold, encoders, torque), so nothing here re-implements them.

Row values are float64 (integers and booleans exactly representable); NaN marks a value
not computed at this tick, as in `TickRecord`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np
import numpy.typing as npt
from numba import njit

from controller.actuator import TorqueModel, torque_at
from controller.config import ControllerConfig
from controller.decision import decide_fast
from controller.device.base import ENCODER_COUNTS, Status
from controller.encoders import EncoderLayout, count_to_angle
from controller.intent import _intent_kernel
from controller.kalman import HipVelocityFilter, kalman_step
from controller.lowlevel import LockHold, hold_update
from controller.onset import ModelBank, ObservationWindow, _bank_kernel, window_push, window_start
from controller.plausibility import (
    ALPHA_RANGE,
    ANGLE_NOISE_RAD,
    HIP_ACCELERATION_MAX,
    HIP_VELOCITY_MAX,
    MIN_INTERVAL_S,
    Q_RANGE,
    RESYNC_S,
)
from controller.tick import MODEL_NAMES, Action, Plausibility, TickFlag, TickRecord

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


#: Decision modes of `tick`.
MODE_UMC, MODE_EUMC, MODE_PEC = 0, 1, 2

_NAMES = TickRecord.field_names()
#: Columns of the output row: the numeric `TickRecord` fields `q_raw_left` .. `plausibility`.
OUT_FIELDS: tuple[str, ...] = _NAMES[_NAMES.index("q_raw_left") :
                                     _NAMES.index("plausibility") + 1]
N_OUT = len(OUT_FIELDS)
_col = OUT_FIELDS.index
O_QRAW_L, O_QRAW_R, O_Q_L, O_Q_R = (_col(n) for n in ("q_raw_left", "q_raw_right", "q_left",
                                                     "q_right"))
O_W_L, O_W_R, O_TRIG, O_RAN = (_col(n) for n in ("omega_left", "omega_right", "trigger",
                                                "controller_ran"))
#: First column of model j's (d, l, s_start, s_curr, accepted, p_obs) is O_MODEL + 6 j.
O_MODEL = _col("d_squat")
O_POST, O_EU = _col("post_squat"), _col("eu_no_lock")
O_ACTION, O_LOCK_L, O_LOCK_R = _col("action"), _col("lock_left"), _col("lock_right")
O_LOCKED_L, O_LOCKED_R = _col("locked_left"), _col("locked_right")
O_ALPHA_L, O_ALPHA_R = _col("alpha_left"), _col("alpha_right")
O_TORQUE_L, O_TORQUE_R, O_FLAGS = _col("torque_left"), _col("torque_right"), _col("flags")
O_PLAUS = _col("plausibility")
assert OUT_FIELDS[O_MODEL : O_MODEL + 6] == ("d_squat", "l_squat", "s_start_squat",
                                             "s_curr_squat", "accepted_squat", "p_obs_squat")
assert OUT_FIELDS[O_MODEL + 6 * len(MODEL_NAMES)] == "post_squat"
assert OUT_FIELDS[O_EU : O_EU + 4] == ("eu_no_lock", "eu_lock_both", "eu_lock_right",
                                       "eu_lock_left")

# Constants in `cfg_f` and `cfg_i`.
F_THRESHOLD, F_OFF_L, F_OFF_R, F_DEADBAND, F_Q_LO, F_Q_HI = range(6)
F_A_LO, F_A_HI, F_VMAX, F_NOISE, F_MIN_DT, F_RESYNC, F_AMAX = range(6, 13)
N_CFG_F = 13
# Plausibility state in `pl`: a reference exists, its device time and raw hip angles, the
# device time of the last sample seen (accepted or not), and the velocity between the last
# two accepted samples (if there were two).
P_HAVE, P_T, P_QL, P_QR, P_T_SEEN, P_HAVE_V, P_VL, P_VR = range(8)
N_PL = 8
I_MODE, I_DIVIDER, I_CALIBRATED, I_HOLD, I_RADIUS, I_LAYOUT = range(6)
N_CFG_I = I_LAYOUT + 8  # layout offsets (4) then directions (4)
# Controller state in `ctl`: tick index, E-UMC ticks since the trigger rose, last action.
C_TICK, C_SINCE, C_LAST = range(3)

_NO_LOCK, _LOCK_BOTH, _LOCK_RIGHT, _LOCK_LEFT = (int(a) for a in Action)
_BAD = int(TickFlag.BAD_SAMPLE)
_FAULT = int(TickFlag.DEVICE_FAULT)
_ERROR = int(TickFlag.CONTROLLER_ERROR)
_NOT_CAL = int(TickFlag.NOT_CALIBRATED)
_HARD = int(TickFlag.HARD_STOP)
_IMPL = int(TickFlag.IMPLAUSIBLE)
_PJUMP, _PVEL, _PREP, _PBACK, _PEARLY, _PRANGE, _PRESYNC, _PACC = (int(b) for b in (
    Plausibility.JUMP, Plausibility.VELOCITY, Plausibility.REPEATED,
    Plausibility.TIME_BACKWARDS, Plausibility.TOO_EARLY, Plausibility.RANGE,
    Plausibility.RESYNC, Plausibility.ACCELERATION))
_S_FAULTS = int(Status.ENCODER_FAULT | Status.SUPPLY_FAULT)
_S_LOCKED_L, _S_LOCKED_R = int(Status.LOCKED_LEFT), int(Status.LOCKED_RIGHT)
_S_HARD = int(Status.HARD_STOP_LEFT | Status.HARD_STOP_RIGHT)
_N_MODELS = len(MODEL_NAMES)


@njit(cache=True, nogil=True)
def _defaults(out: FloatArray) -> None:
    """A row of values not computed: NaN, except counters, booleans and the action."""
    for i in range(out.shape[0]):
        out[i] = np.nan
    out[O_TRIG] = 0.0
    out[O_RAN] = 0.0
    for j in range(_N_MODELS):
        out[O_MODEL + 6 * j + 1] = 0.0  # L
        out[O_MODEL + 6 * j + 4] = 0.0  # accepted
    out[O_ACTION] = _NO_LOCK
    out[O_LOCK_L] = 0.0
    out[O_LOCK_R] = 0.0
    out[O_LOCKED_L] = 0.0
    out[O_LOCKED_R] = 0.0
    out[O_FLAGS] = 0.0
    out[O_PLAUS] = 0.0


@njit(cache=True, nogil=True)
def _no_new_lock(hold: IntArray, hold_ticks: int, ctl: IntArray, out: FloatArray, flags: int,
                 plaus: int) -> None:
    """Finish a tick that cannot be trusted: no new request, so no new lock; a lock the
    hold already carries (decided on trusted ticks) stays on to its end, because
    dropping a solenoid for one tick mid-seat and raising it again would be a new lock."""
    lock_l, lock_r = hold_update(hold, hold_ticks, False, False)
    ctl[C_TICK] += 1
    out[O_LOCK_L] = 1.0 if lock_l else 0.0
    out[O_LOCK_R] = 1.0 if lock_r else 0.0
    out[O_FLAGS] = flags
    out[O_PLAUS] = plaus


@njit(cache=True, nogil=True)
def check_sample(
    cfg_f: FloatArray, pl: FloatArray, kal_st: FloatArray, kal_k: FloatArray, win_pc: IntArray,
    t: float, q_l: float, q_r: float, a_l: float, a_r: float,
) -> int:
    """The `Plausibility` bits of a well-formed sample (0: plausible), updating the
    reference in `pl`. Bounds: `controller.plausibility`.

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
    if not (cfg_f[F_A_LO] <= a_l <= cfg_f[F_A_HI] and cfg_f[F_A_LO] <= a_r <= cfg_f[F_A_HI]):
        bits |= _PRANGE
    seen = pl[P_T_SEEN]
    first = pl[P_HAVE] == 0.0
    if not first and t == seen:
        return bits | _PREP  # nothing else changes: the same sample again
    pl[P_T_SEEN] = t
    if not first and t < seen:
        kal_st[0] = 0.0  # the filter re-initialises at its next sample
        win_pc[0] = 0
        win_pc[1] = 0
        pl[P_HAVE] = 0.0
        return bits | _PBACK
    if bits:
        return bits
    if first:
        pl[P_HAVE] = 1.0
        pl[P_HAVE_V] = 0.0
        pl[P_T] = t
        pl[P_QL] = q_l
        pl[P_QR] = q_r
        return 0
    dt = t - pl[P_T]
    if dt < cfg_f[F_MIN_DT]:
        return _PEARLY
    if dt > cfg_f[F_RESYNC]:
        kal_st[0] = 0.0
        win_pc[0] = 0
        win_pc[1] = 0
        pl[P_HAVE_V] = 0.0
        pl[P_T] = t
        pl[P_QL] = q_l
        pl[P_QR] = q_r
        return _PRESYNC
    # The bounds grow with the time since the last accepted sample, but only up to two
    # periods: a reading that stays off (an encoder that jumped and stayed) is not let
    # in gradually, as a fast movement would be read from it; it waits for the resync.
    db = min(dt, 2.0 * kal_k[0])
    bound = cfg_f[F_VMAX] * db + cfg_f[F_NOISE]
    if abs(q_l - pl[P_QL]) > bound or abs(q_r - pl[P_QR]) > bound:
        return _PJUMP
    if pl[P_HAVE_V] != 0.0:
        # The velocity is a backward difference (half a period old), so the hip can be
        # a * dt^2 off its course, not a * dt^2 / 2.
        reach = cfg_f[F_AMAX] * db * db + cfg_f[F_NOISE]
        if (abs(q_l - pl[P_QL] - pl[P_VL] * dt) > reach
                or abs(q_r - pl[P_QR] - pl[P_VR] * dt) > reach):
            return _PACC
    for _ in range(round(dt / kal_k[0]) - 1):  # kal_k[0]: the filter's period
        kalman_step(kal_st, kal_k, math.nan, math.nan)  # predict only
    pl[P_VL] = (q_l - pl[P_QL]) / dt
    pl[P_VR] = (q_r - pl[P_QR]) / dt
    pl[P_HAVE_V] = 1.0
    pl[P_T] = t
    pl[P_QL] = q_l
    pl[P_QR] = q_r
    return 0


@njit(cache=True, nogil=True)
def tick(
    cfg_f: FloatArray, cfg_i: IntArray, torque_k: FloatArray,
    kal_st: FloatArray, kal_k: FloatArray, hold: IntArray, win: FloatArray, win_pc: IntArray,
    ctl: IntArray, pl: FloatArray,
    bank_prm: FloatArray, crit: FloatArray, acc: FloatArray, bank_d: FloatArray,
    bank_i: IntArray, bank_s: FloatArray, bank_ok: BoolArray,
    priors: FloatArray, p_obs: FloatArray, post: FloatArray, table: FloatArray, eu: FloatArray,
    c0: int, c1: int, c2: int, c3: int, t: float, status: int, out: FloatArray,
) -> None:
    """One tick: the sample (four counts, device time, `Status` bits) in, `out` row out.

    A sample that cannot be trusted (time not finite, a count out of range, a device
    fault, a hip angle outside `Q_RANGE`) gives a flagged row with no new lock: the hold
    keeps counting (a lock already held runs out), but nothing is newly commanded on a
    tick we cannot trust (`_no_new_lock`). A well-formed sample that a hip cannot
    produce (`check_sample`) is treated the same way, flagged IMPLAUSIBLE with reasons.
    """
    _defaults(out)
    flags = 0
    plaus = 0
    q_raw_l = q_raw_r = alpha_l = alpha_r = 0.0
    if not math.isfinite(t) or not (
        0 <= c0 < ENCODER_COUNTS and 0 <= c1 < ENCODER_COUNTS
        and 0 <= c2 < ENCODER_COUNTS and 0 <= c3 < ENCODER_COUNTS
    ):
        flags = _BAD
    elif status & _S_FAULTS:
        flags = _FAULT
    else:
        lo = I_LAYOUT
        q_raw_l = count_to_angle(c0, cfg_i[lo], cfg_i[lo + 4])
        cam_l = count_to_angle(c1, cfg_i[lo + 1], cfg_i[lo + 5])
        q_raw_r = count_to_angle(c2, cfg_i[lo + 2], cfg_i[lo + 6])
        cam_r = count_to_angle(c3, cfg_i[lo + 3], cfg_i[lo + 7])
        alpha_l = q_raw_l - cam_l
        alpha_r = q_raw_r - cam_r
        if not (cfg_f[F_Q_LO] <= q_raw_l <= cfg_f[F_Q_HI]
                and cfg_f[F_Q_LO] <= q_raw_r <= cfg_f[F_Q_HI]):
            flags = _BAD
            plaus = _PRANGE
        else:
            plaus = check_sample(cfg_f, pl, kal_st, kal_k, win_pc, t, q_raw_l, q_raw_r,
                                 alpha_l, alpha_r)
            if plaus != 0:
                flags = _IMPL
            if plaus & (_PBACK | _PRESYNC):
                # A restarted device, or one whose 100 ms watchdog has let go during the
                # silence: a held lock sent now would be a new lock. Drop it.
                hold[0] = 0
                hold[1] = 0
    if flags != 0:
        _no_new_lock(hold, cfg_i[I_HOLD], ctl, out, flags, plaus)
        return

    q_l = q_raw_l - cfg_f[F_OFF_L]
    q_r = q_raw_r - cfg_f[F_OFF_R]
    w_l, w_r = kalman_step(kal_st, kal_k, q_l, q_r)
    if abs(w_l) > cfg_f[F_VMAX] or abs(w_r) > cfg_f[F_VMAX]:
        # The angles passed the jump bound but the filter says no hip moves like this
        # (a series of glitches just under it): no decision while it says so.
        window_push(win, win_pc, q_l, q_r)
        _no_new_lock(hold, cfg_i[I_HOLD], ctl, out, _IMPL, _PVEL)
        return
    trig = w_l >= cfg_f[F_THRESHOLD] and w_r >= cfg_f[F_THRESHOLD]
    window_push(win, win_pc, q_l, q_r)
    size = win.shape[0] // 2
    full = win_pc[1] == size

    # The decision: which controller runs at this tick, and what it decides.
    mode = cfg_i[I_MODE]
    divider = cfg_i[I_DIVIDER]
    ran = False
    run_umc = False
    action = _NO_LOCK
    if mode == MODE_PEC:
        if ctl[C_TICK] % divider == 0:
            ran = True
            action = _LOCK_BOTH if trig else _NO_LOCK
    elif mode == MODE_UMC:
        run_umc = full and ctl[C_TICK] % divider == 0
    elif cfg_i[I_CALIBRATED] == 0:  # E-UMC refuses to run without a calibration
        flags |= _NOT_CAL
    elif not trig:
        ctl[C_SINCE] = -1
        ran = True  # the decision "no lock" is taken at 100 Hz while idle
    else:  # E-UMC triggered: the UMC at the rising edge, then every `divider` ticks
        ctl[C_SINCE] += 1
        run_umc = full and ctl[C_SINCE] % divider == 0
    if run_umc:
        start = window_start(size, win_pc)
        obs = win[start : win_pc[0] + size]
        rc = _bank_kernel(obs, bank_prm, cfg_i[I_RADIUS], crit, acc, bank_d, bank_i, bank_s,
                          bank_ok)
        if rc != 0:  # a NaN in the window; cannot happen with decoded counts
            flags |= _ERROR
        else:
            _intent_kernel(bank_d, bank_i[0], bank_ok, priors, p_obs, post)
            action = decide_fast(table, bank_s[1], post, eu)
            ran = True
            for j in range(_N_MODELS):
                o = O_MODEL + 6 * j
                out[o] = bank_d[j]
                out[o + 1] = bank_i[0, j]
                out[o + 2] = bank_s[0, j]
                out[o + 3] = bank_s[1, j]
                out[o + 4] = 1.0 if bank_ok[j] else 0.0
                out[o + 5] = p_obs[j]
            for j in range(_N_MODELS + 1):
                out[O_POST + j] = post[j]
            for a in range(4):
                out[O_EU + a] = eu[a]
    req_l = req_r = False
    if ran:
        ctl[C_LAST] = action
        req_l = action in (_LOCK_BOTH, _LOCK_LEFT)
        req_r = action in (_LOCK_BOTH, _LOCK_RIGHT)
    lock_l, lock_r = hold_update(hold, cfg_i[I_HOLD], req_l, req_r)
    ctl[C_TICK] += 1

    locked_l = (status & _S_LOCKED_L) != 0 or alpha_l > cfg_f[F_DEADBAND]
    locked_r = (status & _S_LOCKED_R) != 0 or alpha_r > cfg_f[F_DEADBAND]
    if status & _S_HARD:
        flags |= _HARD
    out[O_QRAW_L] = q_raw_l
    out[O_QRAW_R] = q_raw_r
    out[O_Q_L] = q_l
    out[O_Q_R] = q_r
    out[O_W_L] = w_l
    out[O_W_R] = w_r
    out[O_TRIG] = 1.0 if trig else 0.0
    out[O_RAN] = 1.0 if ran else 0.0
    out[O_ACTION] = ctl[C_LAST]
    out[O_LOCK_L] = 1.0 if lock_l else 0.0
    out[O_LOCK_R] = 1.0 if lock_r else 0.0
    out[O_LOCKED_L] = 1.0 if locked_l else 0.0
    out[O_LOCKED_R] = 1.0 if locked_r else 0.0
    out[O_ALPHA_L] = alpha_l
    out[O_ALPHA_R] = alpha_r
    out[O_TORQUE_L] = torque_at(alpha_l, torque_k) if locked_l else 0.0
    out[O_TORQUE_R] = torque_at(alpha_r, torque_k) if locked_r else 0.0
    out[O_FLAGS] = flags


#: `tick` for calls that spread `TickCore.args` (numba's typing cannot follow a spread).
tick_any = cast(Callable[..., None], tick)


@dataclass(frozen=True)
class Decider:
    """The compiled decision's inputs for a UMC or E-UMC: model bank, priors, utilities.

    The arrays are the ones `ModelBank`, `IntentEstimator` and the controller already own,
    so after a tick they hold its results just as the Python calls would have left them.
    """

    bank: ModelBank
    priors: FloatArray
    p_obs: FloatArray
    post: FloatArray
    table: FloatArray
    eu: FloatArray


def _no_decider() -> tuple[FloatArray | IntArray | BoolArray, ...]:
    """Placeholder arrays of the right types for a controller without a model bank (PEC),
    so every controller shares one compiled `tick`."""
    return (
        np.zeros((1, 5, 1)), np.zeros(5), np.zeros((1, 1, 1)), np.zeros(1),
        np.zeros((5, 1), dtype=np.int64), np.zeros((2, 1)), np.zeros(1, dtype=np.bool_),
        np.full(2, 0.5), np.zeros(1), np.zeros(2), np.zeros((4, 4, 1)), np.zeros(4),
    )


def float_constants(c: ControllerConfig) -> FloatArray:
    """The `cfg_f` array of `tick` and `check_sample` for a configuration."""
    offsets = c.calibration if c.calibration is not None else (0.0, 0.0)
    out = np.array([c.velocity_threshold, offsets[0], offsets[1], c.lock_deadband,
                    Q_RANGE[0], Q_RANGE[1], ALPHA_RANGE[0], ALPHA_RANGE[1],
                    HIP_VELOCITY_MAX, ANGLE_NOISE_RAD, MIN_INTERVAL_S, RESYNC_S,
                    HIP_ACCELERATION_MAX])
    assert out.size == N_CFG_F
    return out


class SampleChecker:
    """`check_sample` on its own, for a controller that decides nothing (recording mode):
    its ticks carry the same plausibility flags as every other controller's."""

    def __init__(self) -> None:
        self.cfg_f = float_constants(ControllerConfig())
        self.state = np.zeros(N_PL)
        # The check restarts or advances a velocity filter and a window; here they only
        # keep `check_sample`'s signature (nothing reads them).
        self._filter = HipVelocityFilter()
        self._window = np.zeros(2, dtype=np.int64)

    def reset(self) -> None:
        """Forget the reference."""
        self.state[:] = 0.0

    def check(self, t: float, q_l: float, q_r: float, a_l: float, a_r: float) -> int:
        """The `Plausibility` bits of one decoded sample (0: plausible)."""
        if not (Q_RANGE[0] <= q_l <= Q_RANGE[1] and Q_RANGE[0] <= q_r <= Q_RANGE[1]):
            return int(_PRANGE)
        return int(check_sample(self.cfg_f, self.state, self._filter.state,
                                self._filter.constants, self._window, t, q_l, q_r, a_l, a_r))


def layout_array(layout: EncoderLayout) -> IntArray:
    """Offsets then directions of an encoder layout, as the kernels read them."""
    return np.array([*layout.offsets, *layout.directions], dtype=np.int64)


class TickCore:
    """All per-tick state of one controller in preallocated arrays, and `tick` over them.

    Built once per controller. `step` runs one live tick; `PipelineController` and the
    batch replay (`controller.replay`) both go through it.
    """

    def __init__(
        self, config: ControllerConfig, mode: int, divider: int, decider: Decider | None = None
    ) -> None:
        c = config
        if mode not in (MODE_UMC, MODE_EUMC, MODE_PEC):
            raise ValueError(f"unknown decision mode {mode!r}")
        if mode != MODE_PEC and decider is None:
            raise ValueError("the UMC and E-UMC need a model bank, priors and utilities")
        if divider < 1:
            raise ValueError(f"divider must be >= 1 tick, got {divider}")
        self.mode = mode
        self.torque = TorqueModel(c.precompression_pct)
        # The Python objects own the arrays `tick` updates, so their properties (filtered
        # angles, gains, remaining hold, the window) show the live state.
        self.velocity = HipVelocityFilter(accel_std=c.accel_std, meas_std=c.meas_std)
        self.hold = LockHold(c.hold_s)
        self.window = ObservationWindow(c.window)
        self.ctl = np.array([0, -1, _NO_LOCK], dtype=np.int64)
        self.cfg_f = float_constants(c)
        #: Plausibility reference (see `check_sample`).
        self.plaus = np.zeros(N_PL)
        radius = -1 if c.band is None else int(c.band)
        if decider is not None:
            radius = decider.bank.radius
        self.cfg_i = np.array(
            [mode, divider, int(c.calibration is not None), self.hold.hold_ticks,
             radius, *layout_array(c.layout)], dtype=np.int64,
        )
        if decider is not None:
            b = decider.bank
            if b.max_window < c.window:
                raise ValueError(f"model bank window {b.max_window} < window {c.window}")
            dec: tuple[FloatArray | IntArray | BoolArray, ...] = (
                *b.kernel_arrays(), decider.priors, decider.p_obs, decider.post,
                decider.table, decider.eu,
            )
        else:
            dec = _no_decider()
        self.out = np.empty(N_OUT)
        #: The state and constant arguments of `tick`, in its order.
        self.args: tuple[FloatArray | IntArray | BoolArray, ...] = (
            self.cfg_f, self.cfg_i, self.torque.constants, self.velocity.state,
            self.velocity.constants, self.hold.counters, self.window.buffer,
            self.window.pos_count, self.ctl, self.plaus, *dec,
        )

    def reset(self) -> None:
        """Forget filter, window, held locks, tick count, trigger phase and last action."""
        self.velocity.reset()
        self.window.reset()
        self.hold.reset()
        self.ctl[:] = (0, -1, _NO_LOCK)
        self.plaus[:] = 0.0

    @property
    def tick_index(self) -> int:
        """Ticks processed since the last reset (bad ones included)."""
        return int(self.ctl[C_TICK])

    def warm_up(self) -> None:
        """Compile `tick` (or load it from the numba cache) without touching the state."""
        scratch = tuple(a.copy() for a in self.args)
        tick_any(*scratch, 3100, 3100, 12900, 12900, 0.0, 0, np.empty(N_OUT))

    def step(self, c0: int, c1: int, c2: int, c3: int, t: float, status: int) -> FloatArray:
        """One tick; returns the output row (reused: read it before the next step)."""
        tick_any(*self.args, c0, c1, c2, c3, t, status, self.out)
        return self.out
