"""The tick record: everything one control-loop tick knows, in one flat, typed row.

It is produced by every controller (live, replay, simulation), sent from the worker
process to the server, stored one row per tick, streamed to browsers and exported.
Flat scalar fields keep it a plain table row in SQL, CSV and JSON alike. `NaN` marks a
value a controller did not compute at this tick (for example DTW outputs on ticks where
a 10 Hz UMC did not run).
"""

from __future__ import annotations

import enum
import keyword
import math
import operator
from collections.abc import Callable
from dataclasses import MISSING, dataclass, fields
from typing import Any

import numpy.typing as npt

MODEL_NAMES: tuple[str, str, str] = ("squat", "stoop_left", "stoop_right")
CATEGORY_NAMES: tuple[str, str, str, str] = (*MODEL_NAMES, "other")


class Action(enum.IntEnum):
    """The paper's actions a1..a4."""

    NO_LOCK = 1
    LOCK_BOTH = 2
    LOCK_RIGHT = 3
    LOCK_LEFT = 4

    @property
    def locks(self) -> tuple[bool, bool]:
        """(left, right) solenoid commands for this action."""
        return {
            Action.NO_LOCK: (False, False),
            Action.LOCK_BOTH: (True, True),
            Action.LOCK_RIGHT: (False, True),
            Action.LOCK_LEFT: (True, False),
        }[self]


ACTION_NAMES: tuple[str, str, str, str] = ("no_lock", "lock_both", "lock_right", "lock_left")


class TickFlag(enum.IntFlag):
    """Why a tick is not a normal one. A flagged tick never carries a lock decision
    other than the held one, and a bad sample always yields no new lock."""

    NONE = 0
    BAD_SAMPLE = 1 << 0  # NaN, out of range or faulty encoder reading
    DEVICE_FAULT = 1 << 1  # the device reported a fault bit
    CONTROLLER_ERROR = 1 << 2  # the high-level controller raised; the tick fell back to no lock
    OVERRUN = 1 << 3  # the loop missed its period before this tick
    NOT_CALIBRATED = 1 << 4  # the controller needs a calibration it does not have
    HARD_STOP = 1 << 5  # a locked side reached the 22 mm compression limit
    GAP = 1 << 6  # device sequence numbers skipped before this sample
    IMPLAUSIBLE = 1 << 7  # failed a plausibility check: the `plausibility` column says which


class Plausibility(enum.IntFlag):
    """Why a well-formed sample cannot be a human hip in this exoskeleton (the
    `plausibility` column). Bounds and their sources: `controller.lowlevel.plausibility`."""

    OK = 0
    JUMP = 1 << 0  # hip angle moved faster than a hip can since the last good sample
    VELOCITY = 1 << 1  # filtered hip velocity beyond what a hip does
    REPEATED = 1 << 2  # device time did not advance: a repeated or stale sample
    TIME_BACKWARDS = 1 << 3  # device time went back: the device restarted or was replaced
    TOO_EARLY = 1 << 4  # less than half a period after the last good sample
    RANGE = 1 << 5  # hip flexion or spring deflection outside the mechanism's range
    RESYNC = 1 << 6  # first sample after a silence: filters restart from here
    ACCELERATION = 1 << 7  # off the course the hip was on by more than a hip can turn


NAN = math.nan


@dataclass(frozen=True, slots=True)
class TickRecord:
    """One control tick. Angles in radians, velocities in rad/s, torques in Nm, times in s."""

    seq: int
    t: float  # device timestamp
    t_host: float = NAN  # wall-clock time (Unix seconds) at which the worker read the sample
    count_left_output: int = 0
    count_left_cam: int = 0
    count_right_output: int = 0
    count_right_cam: int = 0
    q_raw_left: float = NAN
    q_raw_right: float = NAN
    q_left: float = NAN  # calibrated
    q_right: float = NAN
    omega_left: float = NAN
    omega_right: float = NAN
    trigger: bool = False
    controller_ran: bool = False
    d_squat: float = NAN
    l_squat: int = 0
    s_start_squat: float = NAN
    s_curr_squat: float = NAN
    accepted_squat: bool = False
    p_obs_squat: float = NAN
    d_stoop_left: float = NAN
    l_stoop_left: int = 0
    s_start_stoop_left: float = NAN
    s_curr_stoop_left: float = NAN
    accepted_stoop_left: bool = False
    p_obs_stoop_left: float = NAN
    d_stoop_right: float = NAN
    l_stoop_right: int = 0
    s_start_stoop_right: float = NAN
    s_curr_stoop_right: float = NAN
    accepted_stoop_right: bool = False
    p_obs_stoop_right: float = NAN
    post_squat: float = NAN
    post_stoop_left: float = NAN
    post_stoop_right: float = NAN
    post_other: float = NAN
    eu_no_lock: float = NAN
    eu_lock_both: float = NAN
    eu_lock_right: float = NAN
    eu_lock_left: float = NAN
    action: int = int(Action.NO_LOCK)
    lock_left: bool = False  # held solenoid command actually sent
    lock_right: bool = False
    locked_left: bool = False  # mechanism state, from the device
    locked_right: bool = False
    alpha_left: float = NAN
    alpha_right: float = NAN
    torque_left: float = NAN
    torque_right: float = NAN
    flags: int = 0
    plausibility: int = 0  # `Plausibility` bits; 0 for a plausible sample
    compute_us: float = NAN  # time spent in the controller for this tick
    truth_activity: str = ""  # simulated wearer's ground truth, empty for real hardware
    truth_lift: int = -1
    truth_progress: float = NAN

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """Column order used by the database, CSV export and the stream."""
        return _FIELD_NAMES

    @classmethod
    def field_types(cls) -> dict[str, type]:
        """Field name to its Python type (`int`, `float`, `bool` or `str`): how a column
        of numbers maps back onto record values."""
        return dict(_FIELD_TYPES)

    def as_tuple(self) -> tuple[Any, ...]:
        """Values in `field_names()` order. Every field is a scalar, so one attribute
        getter does what `dataclasses.astuple` does, without its recursive copying (which
        made storing 100 Hz ticks at simulation speed CPU-bound)."""
        return _FIELD_GETTER(self)

    def as_dict(self) -> dict[str, Any]:
        """Field name to value; NaN is kept (callers that emit JSON map it to null)."""
        return dict(zip(_FIELD_NAMES, self.as_tuple(), strict=True))

    def with_(self, **changes: Any) -> TickRecord:
        """A copy with some fields changed (records are immutable once made). What
        `dataclasses.replace` does, from the values as one tuple: `replace` gathers
        every field by name first, which cost several records' worth per tick."""
        values = list(_FIELD_GETTER(self))
        for name, value in changes.items():
            i = _FIELD_INDEX.get(name)
            if i is None:
                raise TypeError(f"TickRecord has no field {name!r}")
            values[i] = value
        return TickRecord(*values)


_FIELD_NAMES: tuple[str, ...] = tuple(f.name for f in fields(TickRecord))
_FIELD_INDEX: dict[str, int] = {n: i for i, n in enumerate(_FIELD_NAMES)}
_FIELD_GETTER = operator.attrgetter(*_FIELD_NAMES)


def _slot_setting_init() -> Callable[..., None]:
    """`TickRecord.__init__` with the dataclass's signature, defaults and annotations,
    storing each field through its slot's descriptor.

    The dataclass writes a frozen class's fields with `object.__setattr__(self, name,
    value)`, a lookup by name per field: for 55 fields that made building a record
    cost more than the rest of a simulated tick. The slot descriptors store the same
    values without it (the class stays frozen: assignment still raises). Generated
    as the dataclass generates its own, since a signature of 55 named parameters is
    what keyword construction needs.
    """
    params, body = [], []
    scope: dict[str, Any] = {}
    for f in fields(TickRecord):
        assert f.name.isidentifier() and not keyword.iskeyword(f.name), f.name
        if f.default is MISSING:
            params.append(f.name)
        else:
            params.append(f"{f.name}=_default_{f.name}")
            scope[f"_default_{f.name}"] = f.default
        scope[f"_set_{f.name}"] = getattr(TickRecord, f.name).__set__
        body.append(f"    _set_{f.name}(self, {f.name})")
    source = f"def __init__(self, {', '.join(params)}):\n" + "\n".join(body) + "\n"
    exec(source, scope)  # our own field names, checked above
    init: Callable[..., None] = scope["__init__"]
    original = TickRecord.__init__
    init.__qualname__ = original.__qualname__
    init.__annotations__ = dict(original.__annotations__)
    init.__doc__ = original.__doc__
    return init


setattr(TickRecord, "__init__", _slot_setting_init())  # noqa: B010 - mypy: no method assignment
_FIELD_TYPES: dict[str, type] = {
    f.name: {"int": int, "float": float, "bool": bool, "str": str}[str(f.type)]
    for f in fields(TickRecord)
}

#: A run of ticks as columns: field name to a (K,) array (int64, float64, bool, or
#: unicode/object for strings), in `TickRecord.field_names()` order. What the batch
#: replay produces: 60,000 ticks as 55 arrays rather than 60,000 objects. Conversions
#: to and from records, rows, JSON and CSV: `controller.tick_codec`.
TickColumns = dict[str, npt.NDArray[Any]]


#: Units and meanings of every field, for exports and the data dictionary.
TICK_FIELD_DOCS: dict[str, tuple[str, str]] = {
    "seq": ("", "device sample sequence number"),
    "t": ("s", "device timestamp"),
    "t_host": ("s", "Unix time at which the worker read the sample"),
    "count_left_output": ("count", "raw 14-bit count, left output-link encoder"),
    "count_left_cam": ("count", "raw 14-bit count, left cam-link encoder"),
    "count_right_output": ("count", "raw 14-bit count, right output-link encoder"),
    "count_right_cam": ("count", "raw 14-bit count, right cam-link encoder"),
    "q_raw_left": ("rad", "left hip flexion from the encoder, flexion positive"),
    "q_raw_right": ("rad", "right hip flexion from the encoder, flexion positive"),
    "q_left": ("rad", "left hip flexion after calibration offset"),
    "q_right": ("rad", "right hip flexion after calibration offset"),
    "omega_left": ("rad/s", "left hip flexion velocity (Kalman filter)"),
    "omega_right": ("rad/s", "right hip flexion velocity (Kalman filter)"),
    "trigger": ("bool", "velocity trigger: both hips flexing at or above the threshold"),
    "controller_ran": ("bool", "the high-level controller evaluated at this tick"),
    "action": ("1-4", "decided action: 1 no lock, 2 lock both, 3 lock right, 4 lock left"),
    "lock_left": ("bool", "left solenoid command sent (after the 0.3 s hold)"),
    "lock_right": ("bool", "right solenoid command sent (after the 0.3 s hold)"),
    "locked_left": ("bool", "left ratchet engaged, as reported by the device"),
    "locked_right": ("bool", "right ratchet engaged, as reported by the device"),
    "alpha_left": ("rad", "left spring deflection, output minus cam link"),
    "alpha_right": ("rad", "right spring deflection, output minus cam link"),
    "torque_left": ("Nm", "left exoskeleton extension torque from the actuator model"),
    "torque_right": ("Nm", "right exoskeleton extension torque from the actuator model"),
    "flags": ("bits", "TickFlag bits: 1 bad sample, 2 device fault, 4 controller error, "
              "8 overrun, 16 not calibrated, 32 hard stop, 64 sequence gap, "
              "128 implausible sample"),
    "plausibility": ("bits", "why the sample is implausible: 1 angle jump, 2 hip velocity, "
                     "4 repeated sample, 8 device time backwards, 16 sample too early, "
                     "32 out of mechanical range, 64 first sample after a silence, "
                     "128 acceleration"),
    "compute_us": ("us", "controller compute time for this tick"),
    "truth_activity": ("", "simulated ground truth: activity (empty for real hardware)"),
    "truth_lift": ("", "simulated ground truth: lift index within the trial, -1 if none"),
    "truth_progress": ("0-1", "simulated ground truth: progress within the lift"),
    "post_other": ("0-1", "posterior probability of category other"),
    "eu_no_lock": ("", "expected utility of action a1, no lock (Nm^2, negative)"),
    "eu_lock_both": ("", "expected utility of action a2, lock both (Nm^2, negative)"),
    "eu_lock_right": ("", "expected utility of action a3, lock right (Nm^2, negative)"),
    "eu_lock_left": ("", "expected utility of action a4, lock left (Nm^2, negative)"),
}
for _m in MODEL_NAMES:
    TICK_FIELD_DOCS.update(
        {
            f"d_{_m}": ("", f"accumulated Mahalanobis DTW cost of the best path, {_m} model"),
            f"l_{_m}": ("cells", f"number of cells on the best DTW path, {_m} model"),
            f"s_start_{_m}": ("0-1", f"model progress at the start of the path, {_m} model"),
            f"s_curr_{_m}": ("0-1", f"model progress at the end of the path, {_m} model"),
            f"accepted_{_m}": ("bool", f"the match passed the three acceptance criteria, {_m}"),
            f"p_obs_{_m}": ("0-1", f"P(obs | {_m}) from the chi-square survival function"),
            f"post_{_m}": ("0-1", f"posterior probability of {_m}"),
        }
    )
assert set(TICK_FIELD_DOCS) == set(_FIELD_NAMES), set(_FIELD_NAMES) ^ set(TICK_FIELD_DOCS)
