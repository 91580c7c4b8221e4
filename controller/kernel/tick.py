"""The compiled tick every controller shares, around the controller's decision step.

A tick is `begin`, the controller's decision, then `finish`:

- `begin(state, c0, c1, c2, c3, t, status, rows, k)`: counts to angles, the
  plausibility check, calibration offsets, Kalman velocities, the trigger and the
  observation window. It writes what it computed into `rows[k]` and returns whether
  the sample can be decided on; if not, it has finished the row itself (flagged, no new
  lock).
- `decide(state, data, row) -> (ran, action, flags)`: the controller's decision step
  (in the controller's module). It reads the settings (`state.settings[0]`), the phase
  (`state.phase[0]`, which it may update), the window (`state.window`,
  `state.window_pos`), its own `data` and this tick's trigger (`row.trigger`), may fill
  the row fields it computes, and returns whether it decided at this tick, the action
  (an `Action`, read only if it ran) and `TickFlag` bits to add.
- `finish(state, decision, status, rows, k)`: the action becomes lock requests, the
  lock hold turns them into this tick's commands, then mechanism state and torque.

The two entry points with a controller's decision in between (`step`, one live tick;
`batch`, the batch replay with `replay_sample` stepping the simulated mechanism between
ticks) are built by `controller.kernel.entry_points`. The flow is described in
`docs/controller-kernel.md`.
"""

from __future__ import annotations

import math

from numba import njit

from controller.device.base import ENCODER_COUNTS, Status
from controller.intent.kalman import kalman_step
from controller.intent.onset import window_push
from controller.kernel.check import PRESYNC_OR_BACK, RANGE, VELOCITY, check_sample
from controller.lowlevel.actuator import torque_at
from controller.lowlevel.encoders import angle_to_count, count_to_angle
from controller.lowlevel.lock_hold import hold_update
from controller.sim.plant import CAM, OUTPUT, plant_step
from controller.tick_record import Action, TickFlag

NO_LOCK, LOCK_BOTH, LOCK_RIGHT, LOCK_LEFT = (int(a) for a in Action)
BAD_SAMPLE = int(TickFlag.BAD_SAMPLE)
DEVICE_FAULT = int(TickFlag.DEVICE_FAULT)
CONTROLLER_ERROR = int(TickFlag.CONTROLLER_ERROR)
NOT_CALIBRATED = int(TickFlag.NOT_CALIBRATED)
HARD_STOP = int(TickFlag.HARD_STOP)
IMPLAUSIBLE = int(TickFlag.IMPLAUSIBLE)
_S_FAULTS = int(Status.ENCODER_FAULT | Status.SUPPLY_FAULT)
_S_LOCKED_L, _S_LOCKED_R = int(Status.LOCKED_LEFT), int(Status.LOCKED_RIGHT)
_S_HARD = int(Status.HARD_STOP_LEFT | Status.HARD_STOP_RIGHT)


@njit(cache=True, nogil=True)
def triggered(omega_left: float, omega_right: float, threshold: float) -> bool:
    """The paper's trigger: both hips flexing at or above `threshold` rad/s (NaN: no)."""
    return omega_left >= threshold and omega_right >= threshold


@njit(cache=True, nogil=True)
def window_full(state) -> bool:  # type: ignore[no-untyped-def]
    """The observation window holds as many samples as it is long."""
    return bool(state.window_pos[1] == state.window.shape[0] // 2)


@njit(cache=True, nogil=True)
def _no_new_lock(state, ph, row, flags: int, plaus: int) -> None:  # type: ignore[no-untyped-def]
    """Finish a tick that cannot be trusted: no new request, so no new lock; a lock the
    hold already carries (decided on trusted ticks) stays on to its end, because
    dropping a solenoid for one tick mid-seat and raising it again would be a new lock."""
    lock_l, lock_r = hold_update(state.hold, state.settings[0].hold_ticks, False, False)
    ph.tick += 1
    row.lock_left = 1.0 if lock_l else 0.0
    row.lock_right = 1.0 if lock_r else 0.0
    row.flags = flags
    row.plausibility = plaus


@njit(cache=True, nogil=True)
def begin(  # type: ignore[no-untyped-def]
    state, c0: int, c1: int, c2: int, c3: int, t: float, status: int, rows, k: int,
) -> bool:
    """The sample (four counts, device time, `Status` bits) up to the decision, into
    `rows[k]`; True if the decision may run on it.

    A sample that cannot be trusted (time not finite, a count out of range, a device
    fault, a hip angle outside the range, or a well-formed sample a hip cannot produce:
    `check_sample`) gives a flagged row with no new lock: the hold keeps counting (a
    lock already held runs out), but nothing is newly commanded on such a tick.
    """
    rows[k] = state.blank[0]
    row = rows[k]
    s = state.settings[0]
    ph = state.phase[0]
    flags = 0
    plaus = 0
    q_raw_l = q_raw_r = alpha_l = alpha_r = 0.0
    if not math.isfinite(t) or not (
        0 <= c0 < ENCODER_COUNTS and 0 <= c1 < ENCODER_COUNTS
        and 0 <= c2 < ENCODER_COUNTS and 0 <= c3 < ENCODER_COUNTS
    ):
        flags = BAD_SAMPLE
    elif status & _S_FAULTS:
        flags = DEVICE_FAULT
    else:
        q_raw_l = count_to_angle(c0, s.offset_0, s.direction_0)
        cam_l = count_to_angle(c1, s.offset_1, s.direction_1)
        q_raw_r = count_to_angle(c2, s.offset_2, s.direction_2)
        cam_r = count_to_angle(c3, s.offset_3, s.direction_3)
        alpha_l = q_raw_l - cam_l
        alpha_r = q_raw_r - cam_r
        if not (s.q_lo <= q_raw_l <= s.q_hi and s.q_lo <= q_raw_r <= s.q_hi):
            flags = BAD_SAMPLE
            plaus = RANGE
        else:
            plaus = check_sample(s, state.reference[0], state.velocity,
                                 state.velocity_constants, state.window_pos, t, q_raw_l,
                                 q_raw_r, alpha_l, alpha_r)
            if plaus != 0:
                flags = IMPLAUSIBLE
            if plaus & PRESYNC_OR_BACK:
                # A restarted device, or one whose 100 ms watchdog has let go during the
                # silence: a held lock sent now would be a new lock. Drop it.
                state.hold[0] = 0
                state.hold[1] = 0
    if flags != 0:
        _no_new_lock(state, ph, row, flags, plaus)
        return False

    q_l = q_raw_l - s.offset_left
    q_r = q_raw_r - s.offset_right
    w_l, w_r = kalman_step(state.velocity, state.velocity_constants, q_l, q_r)
    if abs(w_l) > s.velocity_max or abs(w_r) > s.velocity_max:
        # The angles passed the jump bound but the filter says no hip moves like this
        # (a series of glitches just under it): no decision while it says so.
        window_push(state.window, state.window_pos, q_l, q_r)
        _no_new_lock(state, ph, row, IMPLAUSIBLE, VELOCITY)
        return False
    trig = triggered(w_l, w_r, s.velocity_threshold)
    window_push(state.window, state.window_pos, q_l, q_r)
    row.q_raw_left = q_raw_l
    row.q_raw_right = q_raw_r
    row.q_left = q_l
    row.q_right = q_r
    row.omega_left = w_l
    row.omega_right = w_r
    row.trigger = 1.0 if trig else 0.0
    row.alpha_left = alpha_l
    row.alpha_right = alpha_r
    return True


@njit(cache=True, nogil=True)
def finish(state, decision, status: int, rows, k: int) -> None:  # type: ignore[no-untyped-def]
    """The decision `(ran, action, flags)` to this tick's lock commands, then mechanism
    state and torque, into `rows[k]` (after `begin` returned True)."""
    row = rows[k]
    s = state.settings[0]
    ph = state.phase[0]
    ran, action, flags = decision
    req_l = req_r = False
    if ran:
        ph.last = action
        req_l = action in (LOCK_BOTH, LOCK_LEFT)
        req_r = action in (LOCK_BOTH, LOCK_RIGHT)
    lock_l, lock_r = hold_update(state.hold, s.hold_ticks, req_l, req_r)
    ph.tick += 1

    alpha_l = row.alpha_left
    alpha_r = row.alpha_right
    locked_l = (status & _S_LOCKED_L) != 0 or alpha_l > s.lock_deadband
    locked_r = (status & _S_LOCKED_R) != 0 or alpha_r > s.lock_deadband
    if status & _S_HARD:
        flags |= HARD_STOP
    row.controller_ran = 1.0 if ran else 0.0
    row.action = ph.last
    row.lock_left = 1.0 if lock_l else 0.0
    row.lock_right = 1.0 if lock_r else 0.0
    row.locked_left = 1.0 if locked_l else 0.0
    row.locked_right = 1.0 if locked_r else 0.0
    row.torque_left = torque_at(alpha_l, state.torque_constants) if locked_l else 0.0
    row.torque_right = torque_at(alpha_r, state.torque_constants) if locked_r else 0.0
    row.flags = flags


@njit(cache=True, nogil=True)
def replay_sample(  # type: ignore[no-untyped-def]
    plant_st, plant_k, layout, q, rows, counts, statuses, k: int,
) -> tuple[int, int, int, int, int]:
    """The device's sample k in a batch replay: (c0, c1, c2, c3, status).

    As `ReplayDevice` does live: the mechanism steps with the lock command of the
    previous tick (`rows[k - 1]`) to the recorded thigh angles `q[k]`, and ideal
    encoders (`layout`: offsets then directions) quantise its links to counts. A gap
    (NaN angle) gives the impossible counts (0, 0, 2^15, 0), hence a bad-sample row, and
    leaves the mechanism untouched. Counts and status are also stored in `counts[k]`
    and `statuses[k]`.
    """
    lock_l = k > 0 and rows[k - 1].lock_left != 0.0
    lock_r = k > 0 and rows[k - 1].lock_right != 0.0
    ql = q[k, 0]
    qr = q[k, 1]
    if math.isfinite(ql) and math.isfinite(qr):
        status = plant_step(plant_st, plant_k, lock_l, lock_r, ql, qr)
        c0 = angle_to_count(plant_st[0, OUTPUT], layout[0], layout[4])
        c1 = angle_to_count(plant_st[0, CAM], layout[1], layout[5])
        c2 = angle_to_count(plant_st[1, OUTPUT], layout[2], layout[6])
        c3 = angle_to_count(plant_st[1, CAM], layout[3], layout[7])
    else:
        status = 0
        c0 = 0
        c1 = 0
        c2 = 1 << 15
        c3 = 0
    counts[k, 0] = c0
    counts[k, 1] = c1
    counts[k, 2] = c2
    counts[k, 3] = c3
    statuses[k] = status
    return c0, c1, c2, c3, status
