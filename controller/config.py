"""Controller configuration: every tunable number of UMC, E-UMC and PEC, as data.

A configuration is stored with the ticks it produced (each run keeps its snapshot), so
any result can be traced to, and replayed with, the exact settings that made it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from controller.encoders import EncoderLayout

SAMPLE_RATE_HZ = 100.0


def ticks_per_run(rate_hz: float, sample_rate_hz: float = SAMPLE_RATE_HZ) -> int:
    """How many 100 Hz ticks lie between two evaluations at `rate_hz`."""
    return max(1, round(sample_rate_hz / rate_hz))


@dataclass(frozen=True)
class ControllerConfig:
    """Parameters of the paper's controllers; defaults are the paper's and controller.md's.

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
        for name in ("umc_rate_hz", "eumc_triggered_rate_hz", "pec_rate_hz"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and 0 < v <= SAMPLE_RATE_HZ):
                raise ValueError(f"{name} must be within (0, 100] Hz, got {v!r}")
        if not 2 <= self.window <= 200:
            raise ValueError(f"window must be 2..200 samples, got {self.window}")
        for name in ("s_req", "t_req", "d_max", "hold_s", "accel_std", "meas_std"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if self.band is not None and self.band < 0:
            raise ValueError(f"band must be None or >= 0 cells, got {self.band}")
        if len(self.priors) != 4 or any(p < 0 for p in self.priors) or not math.isclose(
            sum(self.priors), 1.0, abs_tol=1e-9
        ):
            raise ValueError(f"priors must be 4 values >= 0 summing to 1, got {self.priors}")
        if not 0.0 <= self.precompression_pct <= 100.0:
            raise ValueError(f"precompression_pct must be 0..100, got {self.precompression_pct}")
        if self.calibration is not None and (
            len(self.calibration) != 2 or not all(math.isfinite(c) for c in self.calibration)
        ):
            raise ValueError(f"calibration must be two finite offsets, got {self.calibration}")
        EncoderLayout(self.encoder_offsets, self.encoder_directions)  # validates

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
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown controller setting(s): {', '.join(unknown)}")
        kw: dict[str, Any] = {}
        for k, v in data.items():
            kw[k] = tuple(v) if isinstance(v, list) else v
        return cls(**kw)
