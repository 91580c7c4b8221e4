"""Controller configuration: every tunable number of UMC, E-UMC and PEC, as data.

A configuration is stored with the ticks it produced (each run keeps its snapshot), so
any result can be traced to, and replayed with, the exact settings that made it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from controller.device.base import SAMPLE_RATE_HZ
from controller.lowlevel.encoders import EncoderLayout
from controller.lowlevel.plausibility import HIP_VELOCITY_MAX

#: Largest hip velocity (rad/s) a velocity threshold may ask for: the plausibility bound
#: (a threshold above it could never trigger).
VELOCITY_THRESHOLD_MAX = HIP_VELOCITY_MAX
#: A calibration offset maps a standing posture onto the models' start; beyond 60 deg
#: either way the wearer was not standing (a still moment at the bottom of a squat is
#: about 90 deg) or the encoders are mounted wrongly. `calibrate` refuses such offsets,
#: and a setting cannot carry one.
CALIBRATION_MAX_RAD = math.radians(60.0)

#: (field, lower, upper, lower bound excluded) for every scalar setting.
_BOUNDS: tuple[tuple[str, float, float, bool], ...] = (
    # The trigger must need motion: 0 or less fires while standing still (every tick).
    ("velocity_threshold", 0.0, VELOCITY_THRESHOLD_MAX, True),
    ("s_req", 0.0, 1.0, False),  # a progress difference on s in [0, 1]
    ("t_req", 0.0, 2.0, False),  # a window holds at most 200 samples: 2 s
    ("d_max", 0.0, 1e6, True),  # 0 would reject every match
    # Kalman noises must be positive or the filter gain is undefined; the upper ends
    # are far beyond a hip (1000 rad/s^2) and a 14-bit encoder (0.1 rad).
    ("accel_std", 0.0, 1000.0, True),
    ("meas_std", 0.0, 0.1, True),
    # At least one 10 ms tick, at most 1 s: a pawl seats in well under 0.3 s, and a
    # longer hold would keep a solenoid on through the next step.
    ("hold_s", 0.01, 1.0, False),
    ("precompression_pct", 0.0, 100.0, False),
    ("lock_deadband", 0.0, math.radians(10.0), False),
)


class SettingError(ValueError):
    """A controller setting outside its bounds; `field` names it (for a 422)."""

    def __init__(self, field_name: str, problem: str) -> None:
        super().__init__(f"{field_name}: {problem}")
        self.field = field_name
        self.problem = problem


def _number(name: str, v: object) -> float:
    """`v` as a finite real number, or a `SettingError` naming `name`."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise SettingError(name, f"must be a number, got {v!r}")
    if not math.isfinite(v):
        raise SettingError(name, f"must be a finite number, got {v!r}")
    return float(v)


def _integer(name: str, v: object, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise SettingError(name, f"must be an integer, got {v!r}")
    if not lo <= v <= hi:
        raise SettingError(name, f"must be within {lo}..{hi}, got {v}")
    return v


def ticks_per_run(rate_hz: float, sample_rate_hz: float = SAMPLE_RATE_HZ) -> int:
    """How many 100 Hz ticks lie between two evaluations at `rate_hz`."""
    return max(1, round(sample_rate_hz / rate_hz))


@dataclass(frozen=True)
class ControllerConfig:
    """Parameters of the paper's controllers; defaults are the paper's (and the project's
    choices in docs/controller-design.md where the paper leaves a value open).

    Rates: the paper's UMC ran at 10 Hz, the PEC at 100 Hz, and the E-UMC checks its
    trigger at 100 Hz and evaluates the UMC at 10 Hz while triggered. `at_rate(100)`
    gives this project's option of every controller at 100 Hz.
    """

    umc_rate_hz: float = 10.0
    eumc_triggered_rate_hz: float = 10.0
    pec_rate_hz: float = 100.0
    window: int = 30
    s_req: float = 0.05
    t_req: float = 0.05
    d_max: float = 120.0
    band: int | None = None
    priors: tuple[float, float, float, float] = (0.25, 0.25, 0.25, 0.25)
    velocity_threshold: float = 1.0
    accel_std: float = 15.0
    meas_std: float = 1.05e-3
    hold_s: float = 0.3
    precompression_pct: float = 25.0
    #: Deflection (rad) above which a side is taken as locked when the device does not say.
    lock_deadband: float = math.radians(0.5)
    encoder_offsets: tuple[int, int, int, int] = EncoderLayout().offsets
    encoder_directions: tuple[int, int, int, int] = EncoderLayout().directions
    #: E-UMC calibration offsets (rad, left and right) or None before calibration.
    calibration: tuple[float, float] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # Every bound below is physical or structural, never tuned to a result; the
        # reasons are in `docs/controller-settings.md`. The first broken one is raised,
        # as a `SettingError` naming the field.
        for name in ("umc_rate_hz", "eumc_triggered_rate_hz", "pec_rate_hz"):
            v = _number(name, getattr(self, name))
            if not 0 < v <= SAMPLE_RATE_HZ:
                raise SettingError(name, f"must be within (0, 100] Hz, got {v!r}")
            ratio = SAMPLE_RATE_HZ / v
            if abs(ratio - round(ratio)) > 1e-9:
                raise SettingError(name, f"must divide the 100 Hz sample rate (100, 50, 25, "
                                   f"20, 10, ... Hz), got {v!r}")
        _integer("window", self.window, 2, 200)
        for name, lo, hi, lo_open in _BOUNDS:
            v = _number(name, getattr(self, name))
            if (v <= lo if lo_open else v < lo) or v > hi:
                raise SettingError(name, f"must be within {'(' if lo_open else '['}{lo:g}, "
                                   f"{hi:g}], got {v!r}")
        if self.band is not None:
            _integer("band", self.band, 0, 200)
        if not isinstance(self.priors, tuple | list) or len(self.priors) != 4:
            raise SettingError("priors", f"must be 4 values (squat, stoop_left, stoop_right, "
                               f"other), got {self.priors!r}")
        for p in self.priors:
            if not 0.0 <= _number("priors", p) <= 1.0:
                raise SettingError("priors", f"each must be within [0, 1], got {self.priors}")
        if not math.isclose(sum(self.priors), 1.0, abs_tol=1e-9):
            raise SettingError("priors", f"must sum to 1, got {self.priors} "
                               f"(sum {sum(self.priors)!r})")
        if self.calibration is not None:
            if not isinstance(self.calibration, tuple | list) or len(self.calibration) != 2:
                raise SettingError("calibration", f"must be two offsets (rad), got "
                                   f"{self.calibration!r}")
            for c in self.calibration:
                if abs(_number("calibration", c)) > CALIBRATION_MAX_RAD:
                    raise SettingError("calibration", f"offsets beyond +-"
                                       f"{math.degrees(CALIBRATION_MAX_RAD):.0f} deg are not "
                                       f"a standing posture, got {self.calibration}")
        for name in ("encoder_offsets", "encoder_directions"):
            v = getattr(self, name)
            if not isinstance(v, tuple | list) or len(v) != 4 or not all(
                    isinstance(x, int) and not isinstance(x, bool) for x in v):
                raise SettingError(name, f"must be 4 integers, got {v!r}")
        try:
            EncoderLayout(self.encoder_offsets, self.encoder_directions)
        except ValueError as exc:
            raise SettingError("encoder_offsets", str(exc)) from None
        if not isinstance(self.extra, dict):
            raise SettingError("extra", f"must be a mapping, got {type(self.extra).__name__}")

    @property
    def layout(self) -> EncoderLayout:
        """The encoder mounting."""
        return EncoderLayout(self.encoder_offsets, self.encoder_directions)

    def at_rate(self, rate_hz: float) -> ControllerConfig:
        """The same configuration with every controller at `rate_hz`."""
        return dataclasses.replace(
            self, umc_rate_hz=rate_hz, eumc_triggered_rate_hz=rate_hz, pec_rate_hz=rate_hz
        )

    def with_calibration(self, offset_left: float, offset_right: float) -> ControllerConfig:
        """The same configuration with E-UMC calibration offsets."""
        return dataclasses.replace(self, calibration=(offset_left, offset_right))

    def to_json(self) -> dict[str, Any]:
        """Plain JSON-able dictionary."""
        d = dataclasses.asdict(self)
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ControllerConfig:
        """Inverse of `to_json`; unknown keys are refused by name."""
        if not isinstance(data, dict):
            raise SettingError("settings", f"must be a mapping, got {type(data).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise SettingError(unknown[0], f"unknown controller setting(s): "
                               f"{', '.join(unknown)}")
        kw: dict[str, Any] = {}
        for k, v in data.items():
            kw[k] = tuple(v) if isinstance(v, list) else v
        return cls(**kw)
