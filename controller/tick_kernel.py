"""The compiled control tick: one numba function per 100 Hz tick, live and in replay.

`tick` does what `PipelineController.step` promises (see `controller.pipeline`): check
the sample, counts to angles, calibration offsets, Kalman velocities and the trigger,
the observation window, the decision of the UMC, E-UMC or PEC (an integer mode), the
0.3 s lock hold, the mechanism state and the torque estimate. It writes one row of
numbers (`OUT_FIELDS`, the numeric `TickRecord` fields from `q_raw_left` to `flags`)
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
from controller.tick import MODEL_NAMES, Action, TickFlag, TickRecord

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Hip flexion outside this range (rad) cannot be a human hip: the sample is bad.
Q_RANGE = (math.radians(-60.0), math.radians(160.0))

#: Decision modes of `tick`.
MODE_UMC, MODE_EUMC, MODE_PEC = 0, 1, 2

_NAMES = TickRecord.field_names()
#: Columns of the output row: the numeric `TickRecord` fields `q_raw_left` .. `flags`.
OUT_FIELDS: tuple[str, ...] = _NAMES[_NAMES.index("q_raw_left") : _NAMES.index("flags") + 1]
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
assert OUT_FIELDS[O_MODEL : O_MODEL + 6] == ("d_squat", "l_squat", "s_start_squat",
                                             "s_curr_squat", "accepted_squat", "p_obs_squat")
assert OUT_FIELDS[O_MODEL + 6 * len(MODEL_NAMES)] == "post_squat"
assert OUT_FIELDS[O_EU : O_EU + 4] == ("eu_no_lock", "eu_lock_both", "eu_lock_right",
                                       "eu_lock_left")

# Constants in `cfg_f` and `cfg_i`.
F_THRESHOLD, F_OFF_L, F_OFF_R, F_DEADBAND, F_Q_LO, F_Q_HI = range(6)
N_CFG_F = 6
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


@njit(cache=True, nogil=True)
def tick(
    cfg_f: FloatArray, cfg_i: IntArray, torque_k: FloatArray,
    kal_st: FloatArray, kal_k: FloatArray, hold: IntArray, win: FloatArray, win_pc: IntArray,
    ctl: IntArray,
    bank_prm: FloatArray, crit: FloatArray, acc: FloatArray, bank_d: FloatArray,
    bank_i: IntArray, bank_s: FloatArray, bank_ok: BoolArray,
    priors: FloatArray, p_obs: FloatArray, post: FloatArray, table: FloatArray, eu: FloatArray,
    c0: int, c1: int, c2: int, c3: int, t: float, status: int, out: FloatArray,
) -> None:
    """One tick: the sample (four counts, device time, `Status` bits) in, `out` row out.

    A sample that cannot be trusted (time not finite, a count out of range, a device
    fault, a hip angle outside `Q_RANGE`) gives a flagged row with no lock: the hold
    keeps counting so a later good tick resumes the right state, but nothing is
    commanded on a tick we cannot trust.
    """
    _defaults(out)
    flags = 0
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
    if flags != 0:
        hold_update(hold, cfg_i[I_HOLD], False, False)
        ctl[C_TICK] += 1
        out[O_FLAGS] = flags
        return

    q_l = q_raw_l - cfg_f[F_OFF_L]
    q_r = q_raw_r - cfg_f[F_OFF_R]
    w_l, w_r = kalman_step(kal_st, kal_k, q_l, q_r)
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
        offsets = c.calibration if c.calibration is not None else (0.0, 0.0)
        self.mode = mode
        self.torque = TorqueModel(c.precompression_pct)
        # The Python objects own the arrays `tick` updates, so their properties (filtered
        # angles, gains, remaining hold, the window) show the live state.
        self.velocity = HipVelocityFilter(accel_std=c.accel_std, meas_std=c.meas_std)
        self.hold = LockHold(c.hold_s)
        self.window = ObservationWindow(c.window)
        self.ctl = np.array([0, -1, _NO_LOCK], dtype=np.int64)
        self.cfg_f = np.array([c.velocity_threshold, offsets[0], offsets[1], c.lock_deadband,
                               Q_RANGE[0], Q_RANGE[1]])
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
            self.window.pos_count, self.ctl, *dec,
        )

    def reset(self) -> None:
        """Forget filter, window, held locks, tick count, trigger phase and last action."""
        self.velocity.reset()
        self.window.reset()
        self.hold.reset()
        self.ctl[:] = (0, -1, _NO_LOCK)

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
