"""The hip-module mechanism as plain Python, frozen as the oracle for the compiled one.

This is `controller.sim.plant.HipModule` as it was before its per-tick logic moved into
a numba kernel shared by the live simulator and the batch replay. It is kept verbatim
(only renamed) so `test_plant.py` can check that the compiled mechanism behaves exactly
as the reviewed Python one did, tick for tick, on random command and angle sequences.
"""

from __future__ import annotations

import math

from controller.lowlevel.actuator import (
    PAPER_ACTUATOR,
    MaccepaParams,
    maccepa_torque,
    max_deflection,
)

PULL_IN_S = 0.02
_EPS = 1e-12


class ReferenceHipModule:
    """Ratchet, pawl, springs and hard stop of one side. Angles in radians, joint frame."""

    def __init__(
        self,
        precompression_pct: float = 25.0,
        params: MaccepaParams = PAPER_ACTUATOR,
        tooth_phase: float = 0.0,
        dt: float = 0.01,
        pull_in_s: float = PULL_IN_S,
    ) -> None:
        self.precompression_pct = precompression_pct
        self.params = params
        self.pitch = params.tooth_angle
        self.tooth_phase = tooth_phase
        self.alpha_max = max_deflection(precompression_pct, params)
        self.pull_in_ticks = max(1, round(pull_in_s / dt))
        self.output = 0.0
        self.cam = 0.0
        self.locked = False
        self.hard_stop = False
        self.solenoid = False
        self._energised_ticks = 0

    def reset(self, angle: float) -> None:
        """Unlocked, both links at `angle`."""
        self.output = self.cam = angle
        self.locked = self.hard_stop = self.solenoid = False
        self._energised_ticks = 0

    @property
    def alpha(self) -> float:
        """Spring deflection, output minus cam (>= 0)."""
        return self.output - self.cam

    def torque(self) -> float:
        """Extension torque of the springs (Nm) at the current deflection."""
        if not self.locked:
            return 0.0
        return maccepa_torque(self.alpha, self.precompression_pct, self.params)

    def next_tooth(self, angle: float) -> float:
        """The first tooth position at or above `angle` in the flexion direction."""
        k = math.ceil((angle - self.tooth_phase) / self.pitch - 1e-9)
        return self.tooth_phase + k * self.pitch

    def step(self, solenoid: bool, intended: float) -> None:
        """Advance one tick with the solenoid command and the thigh's intended link angle."""
        self.solenoid = solenoid
        self._energised_ticks = self._energised_ticks + 1 if solenoid else 0
        if self.locked:
            limit = self.cam + self.alpha_max
            self.hard_stop = intended >= limit - _EPS
            self.output = min(intended, limit)
            if self.output <= self.cam:
                # The pawl spring pushes the pawl out at alpha = 0.
                self.locked = False
                self.hard_stop = False
                self.cam = self.output
            return
        self.hard_stop = False
        pawl_on_ratchet = self._energised_ticks >= self.pull_in_ticks
        if pawl_on_ratchet and intended > self.cam:
            tooth = self.next_tooth(self.cam)
            if intended > tooth:
                self.locked = True
                self.cam = tooth
                limit = tooth + self.alpha_max
                self.hard_stop = intended >= limit - _EPS
                self.output = min(intended, limit)
                return
        self.output = self.cam = intended
