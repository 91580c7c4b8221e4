"""The exoskeleton's mechanism and sensors, one hip module per side, stepped at 100 Hz.

Mechanism (`shared/spec/hardware.md`, the paper's "Hardware"):
- The output link follows the thigh; unlocked, the cam link follows the output link.
- The solenoid is driven exactly as commanded; holding a command for 0.3 s is the
  controller's low-level layer's job. The pawl needs the solenoid energised for a
  pull-in time (assumed 20 ms, two ticks, for a 12 V push-pull solenoid of this size)
  before it rides on the ratchet; dropped earlier, nothing happens.
- With the pawl on the ratchet (40 teeth, 9 degree pitch, tooth positions fixed on the
  cam link) flexion carries the cam link to the next tooth, where it is grounded;
  further flexion deflects the spring, `alpha = output - cam`. In extension the pawl
  slides over the teeth and the cam link follows the output: no torque.
- Once engaged, the spring load holds the pawl without current; when alpha returns to
  zero the pawl spring pushes it out and the side is free again (with the solenoid
  still energised it can catch the next tooth on the next flexion).
- Hard stop: the springs cannot compress beyond 22 mm, so the output link cannot pass
  `cam + max_deflection`. The output angle is clamped there and HARD_STOP reported.
- Effect on the wearer: none. The kinematics are prescribed (a documented
  simplification): the exo torque does not change the wearer's motion, except that
  the output link (and so the measured hip angle) cannot pass the hard stop; the
  wearer's intended trajectory resumes when it comes back below it.
Sensors: four AS5048A (14 bit) with Gaussian noise (0.04 deg RMS, plus quantisation
0.006 deg RMS) and a slow non-linearity of the shaft angle (two harmonics, at most
0.75 deg in total), encoded through the `EncoderLayout`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controller.actuator import PAPER_ACTUATOR, MaccepaParams, maccepa_torque, max_deflection
from controller.device.base import Status
from controller.encoders import DEFAULT_LAYOUT, EncoderLayout

PULL_IN_S = 0.02
NOISE_DEG = 0.04
HARDWARE_SEED = 2024  # one exoskeleton for every simulated participant
_EPS = 1e-12


class HipModule:
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


@dataclass(frozen=True, slots=True)
class EncoderModel:
    """Per-encoder non-linearity (two harmonics of the shaft angle) and noise level."""

    amp1: tuple[float, float, float, float]  # rad
    phase1: tuple[float, float, float, float]
    amp2: tuple[float, float, float, float]
    phase2: tuple[float, float, float, float]
    noise_rad: float = math.radians(NOISE_DEG)

    @classmethod
    def from_seed(cls, seed: int = HARDWARE_SEED) -> EncoderModel:
        """A set of four encoders; non-linearity at most 0.75 deg (datasheet: 0.8)."""
        r = np.random.default_rng(np.random.SeedSequence([0xE_4C, seed]))

        def four(lo: float, hi: float) -> tuple[float, float, float, float]:
            v = r.uniform(lo, hi, 4)
            return (float(v[0]), float(v[1]), float(v[2]), float(v[3]))

        a1 = tuple(math.radians(x) for x in four(0.15, 0.5))
        a2 = tuple(math.radians(x) for x in four(0.05, 0.25))
        return cls(
            amp1=(a1[0], a1[1], a1[2], a1[3]),
            phase1=four(0.0, 2.0 * math.pi),
            amp2=(a2[0], a2[1], a2[2], a2[3]),
            phase2=four(0.0, 2.0 * math.pi),
        )

    @classmethod
    def ideal(cls) -> EncoderModel:
        """No non-linearity and no noise (quantisation only)."""
        z = (0.0, 0.0, 0.0, 0.0)
        return cls(z, z, z, z, 0.0)

    def error(self, index: int, angle: float) -> float:
        """Non-linearity (rad) of encoder `index` at joint angle `angle`."""
        return self.amp1[index] * math.sin(angle + self.phase1[index]) + self.amp2[
            index
        ] * math.sin(2.0 * angle + self.phase2[index])


class ExoPlant:
    """Both hip modules and the four encoders: commands and thigh angles in, counts out."""

    def __init__(
        self,
        precompression_pct: float = 25.0,
        layout: EncoderLayout = DEFAULT_LAYOUT,
        encoders: EncoderModel | None = None,
        params: MaccepaParams = PAPER_ACTUATOR,
        dt: float = 0.01,
    ) -> None:
        r = np.random.default_rng(np.random.SeedSequence([0x7007, HARDWARE_SEED]))
        phases = r.uniform(0.0, params.tooth_angle, 2)
        self.left = HipModule(precompression_pct, params, float(phases[0]), dt)
        self.right = HipModule(precompression_pct, params, float(phases[1]), dt)
        self.layout = layout
        self.encoders = encoders if encoders is not None else EncoderModel.from_seed()

    def reset(self, left: float, right: float) -> None:
        """Both sides unlocked at the given link angles."""
        self.left.reset(left)
        self.right.reset(right)

    def step(self, lock_left: bool, lock_right: bool, left: float, right: float) -> Status:
        """Advance both sides one tick; returns the mechanism's status bits."""
        self.left.step(lock_left, left)
        self.right.step(lock_right, right)
        status = Status.NONE
        if lock_left:
            status |= Status.SOLENOID_LEFT
        if lock_right:
            status |= Status.SOLENOID_RIGHT
        if self.left.locked:
            status |= Status.LOCKED_LEFT
        if self.right.locked:
            status |= Status.LOCKED_RIGHT
        if self.left.hard_stop:
            status |= Status.HARD_STOP_LEFT
        if self.right.hard_stop:
            status |= Status.HARD_STOP_RIGHT
        return status

    def link_angles(self) -> tuple[float, float, float, float]:
        """True (left output, left cam, right output, right cam) angles (rad)."""
        return self.left.output, self.left.cam, self.right.output, self.right.cam

    def counts(self, noise: tuple[float, float, float, float]) -> tuple[int, int, int, int]:
        """Encoder readings of the current link angles; `noise` are standard normal draws."""
        enc = self.encoders
        sd = enc.noise_rad
        a = self.link_angles()
        m = [a[i] + enc.error(i, a[i]) + sd * noise[i] for i in range(4)]
        return self.layout.encode(m[0], m[1], m[2], m[3])

    def torques(self) -> tuple[float, float]:
        """Exoskeleton extension torque (Nm), left and right."""
        return self.left.torque(), self.right.torque()
