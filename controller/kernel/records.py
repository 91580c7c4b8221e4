"""The typed records the compiled tick reads and writes, and the output row.

Numba passes numpy structured arrays and named tuples of arrays into compiled code with
their field names, so the tick reads `s.hold_ticks` and writes `row.lock_left` instead
of indexing flat arrays through position constants. Each record is a one-element
structured array (the compiled code takes element 0, a view, and writes through it).

- `SETTINGS`: the constants of one controller run (thresholds, plausibility bounds,
  rate divider, hold length, encoder layout), built once from `ControllerConfig`.
- `REFERENCE`: the plausibility check's memory of the last accepted sample.
- `PHASE`: where the controller is in time: tick count, ticks since the trigger rose,
  last action.
- `ROW`: the output of one tick, the numeric `TickRecord` fields `q_raw_left` ..
  `plausibility`, all float64 (integers and booleans are exact; NaN: not computed).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from controller.config import ControllerConfig
from controller.lowlevel.encoders import EncoderLayout
from controller.lowlevel.plausibility import (
    ALPHA_RANGE,
    ANGLE_NOISE_RAD,
    HIP_ACCELERATION_MAX,
    HIP_VELOCITY_MAX,
    MIN_INTERVAL_S,
    Q_RANGE,
    RESYNC_S,
)
from controller.tick_record import Action, TickRecord

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
RecordArray = npt.NDArray[np.void]

_NAMES = TickRecord.field_names()
#: Fields of the output row: the numeric `TickRecord` fields `q_raw_left` .. `plausibility`
#: (identity, timing and ground truth are the caller's).
ROW_FIELDS: tuple[str, ...] = _NAMES[_NAMES.index("q_raw_left"):
                                     _NAMES.index("plausibility") + 1]
ROW = np.dtype([(n, np.float64) for n in ROW_FIELDS])

SETTINGS = np.dtype([
    ("velocity_threshold", np.float64),  # rad/s, both hips for the trigger
    ("offset_left", np.float64), ("offset_right", np.float64),  # calibration, rad
    ("lock_deadband", np.float64),  # deflection read as locked, rad
    ("q_lo", np.float64), ("q_hi", np.float64),  # hip angle range, rad
    ("alpha_lo", np.float64), ("alpha_hi", np.float64),  # deflection range, rad
    ("velocity_max", np.float64), ("angle_noise", np.float64),  # plausibility bounds
    ("min_interval", np.float64), ("resync", np.float64), ("accel_max", np.float64),
    ("divider", np.int64),  # ticks between two decisions at the controller's rate
    ("calibrated", np.int64),  # 1 if calibration offsets were given
    ("hold_ticks", np.int64),  # lock hold, ticks
    ("radius", np.int64),  # DTW band radius (-1: none)
    # Encoder layout: offsets then directions of the four encoders, in count order.
    ("offset_0", np.int64), ("offset_1", np.int64), ("offset_2", np.int64),
    ("offset_3", np.int64),
    ("direction_0", np.int64), ("direction_1", np.int64), ("direction_2", np.int64),
    ("direction_3", np.int64),
])

REFERENCE = np.dtype([
    ("have", np.int64),  # a reference exists
    ("t", np.float64), ("q_left", np.float64), ("q_right", np.float64),  # last accepted
    ("t_seen", np.float64),  # device time of the last sample seen, accepted or not
    ("have_velocity", np.int64),  # two accepted samples give a velocity
    ("v_left", np.float64), ("v_right", np.float64),
])

PHASE = np.dtype([
    ("tick", np.int64),  # ticks since reset, bad ones included
    ("since", np.int64),  # ticks since the trigger rose (-1: not triggered)
    ("last", np.int64),  # last action decided (an `Action`)
])


class TickState(NamedTuple):
    """Everything one controller's tick reads and updates, shared by every controller.

    The arrays of the building blocks are the ones their Python objects own
    (`HipVelocityFilter`, `LockHold`, `ObservationWindow`, `TorqueModel`), so those
    objects show the compiled state.
    """

    settings: RecordArray  # SETTINGS, one element
    reference: RecordArray  # REFERENCE, one element
    phase: RecordArray  # PHASE, one element
    velocity: FloatArray  # Kalman state
    velocity_constants: FloatArray  # Kalman constants (element 0: the period)
    torque_constants: FloatArray
    hold: IntArray  # ticks left on each side
    window: FloatArray  # doubled ring of (q_left, q_right)
    window_pos: IntArray  # (next slot, count)
    blank: RecordArray  # ROW, one element: the row of a tick that computed nothing


def settings_record(config: ControllerConfig, divider: int, hold_ticks: int,
                    radius: int) -> RecordArray:
    """The `SETTINGS` record of a configuration at a decision divider."""
    c = config
    off = c.calibration if c.calibration is not None else (0.0, 0.0)
    s = np.zeros(1, dtype=SETTINGS)
    r = s[0]
    r["velocity_threshold"] = c.velocity_threshold
    r["offset_left"], r["offset_right"] = off
    r["lock_deadband"] = c.lock_deadband
    r["q_lo"], r["q_hi"] = Q_RANGE
    r["alpha_lo"], r["alpha_hi"] = ALPHA_RANGE
    r["velocity_max"] = HIP_VELOCITY_MAX
    r["angle_noise"] = ANGLE_NOISE_RAD
    r["min_interval"] = MIN_INTERVAL_S
    r["resync"] = RESYNC_S
    r["accel_max"] = HIP_ACCELERATION_MAX
    r["divider"] = divider
    r["calibrated"] = int(c.calibration is not None)
    r["hold_ticks"] = hold_ticks
    r["radius"] = radius
    set_layout(s, c.layout)
    return s


def set_layout(settings: RecordArray, layout: EncoderLayout) -> None:
    """Write an encoder layout into a `SETTINGS` record."""
    for i in range(4):
        settings[0][f"offset_{i}"] = layout.offsets[i]
        settings[0][f"direction_{i}"] = layout.directions[i]


def blank_row() -> RecordArray:
    """The row of a tick that computed nothing: NaN, except the counters, booleans and
    flags (0) and the action (no lock)."""
    row = np.full(1, np.nan, dtype=ROW)
    zero = ["trigger", "controller_ran", "lock_left", "lock_right", "locked_left",
            "locked_right", "flags", "plausibility"]
    for name in ROW_FIELDS:
        if name.startswith(("l_", "accepted_")) or name in zero:
            row[0][name] = 0.0
    row[0]["action"] = int(Action.NO_LOCK)
    return row


def new_reference() -> RecordArray:
    """A plausibility reference that has seen nothing."""
    return np.zeros(1, dtype=REFERENCE)


def new_phase() -> RecordArray:
    """The phase of a controller that has not ticked."""
    p = np.zeros(1, dtype=PHASE)
    reset_phase(p)
    return p


def reset_phase(phase: RecordArray) -> None:
    """Tick 0, not triggered, last action no lock."""
    phase[0]["tick"] = 0
    phase[0]["since"] = -1
    phase[0]["last"] = int(Action.NO_LOCK)
