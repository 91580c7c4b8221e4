"""The exoskeleton's mechanism and sensors, one hip module per side, stepped at 100 Hz.

Mechanism (the paper's "Hardware" section):
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

One mechanism model: the per-tick logic is the compiled `hip_step` / `plant_step` on
state arrays, called by `HipModule` and `ExoPlant` (the live simulator, `ReplayDevice`)
and by the batch replay's compiled loop (`controller.kernel.tick.replay_sample`), so a lock
has the same effect on deflection and torque in every path.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit

from controller.device.base import SAMPLE_PERIOD_S, Status
from controller.lowlevel.actuator import (
    PAPER_ACTUATOR,
    MaccepaParams,
    maccepa_torque,
    max_deflection,
)
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout, angle_to_count

PULL_IN_S = 0.02
NOISE_DEG = 0.04
HARDWARE_SEED = 2024  # one exoskeleton for every simulated participant
_EPS = 1e-12
FloatArray = npt.NDArray[np.float64]


# One side's mechanism state, a float64 row so that the compiled step can update it in
# place: link angles, the three booleans as 0/1 and the solenoid's energised tick count.
# The two link angles' columns are public: the compiled tick's `replay_sample` reads the
# encoder counts of a simulated side from them.
OUTPUT, CAM, _LOCKED, _HARD_STOP, _SOLENOID, _ENERGISED = range(6)
N_STATE = 6
# One side's constants: ratchet pitch, tooth phase, deflection limit, pull-in ticks.
_PITCH, _PHASE, _ALPHA_MAX, _PULL_IN = range(4)
N_PARAMS = 4
LOCKED_LEFT = int(Status.LOCKED_LEFT)
LOCKED_RIGHT = int(Status.LOCKED_RIGHT)
HARD_STOP_LEFT = int(Status.HARD_STOP_LEFT)
HARD_STOP_RIGHT = int(Status.HARD_STOP_RIGHT)
SOLENOID_LEFT = int(Status.SOLENOID_LEFT)
SOLENOID_RIGHT = int(Status.SOLENOID_RIGHT)
#: Every combination of the six bits `plant_step` reports, as `Status` values: looked up
#: per tick instead of constructing the flag (the enum's constructor runs Python code).
_STATUS_OF: tuple[Status, ...] = tuple(Status(bits) for bits in range(64))
# One encoder's constants (a row of `ExoPlant`'s encoder table): the two harmonics of the
# non-linearity and the noise level.
_AMP1, _PHASE1, _AMP2, _PHASE2, _NOISE = range(5)


@njit("float64(float64, float64, float64)", cache=True, nogil=True)
def next_tooth(angle: float, pitch: float, phase: float) -> float:
    """The first tooth position at or above `angle` in the flexion direction."""
    k = math.ceil((angle - phase) / pitch - 1e-9)
    return phase + k * pitch


@njit("void(float64[::1], float64[::1], boolean, float64)", cache=True, nogil=True)
def hip_step(st: FloatArray, prm: FloatArray, solenoid: bool, intended: float) -> None:
    """Advance one side's state `st` one tick (the mechanism of the module docstring).

    The one implementation of the ratchet: `HipModule` (live simulator) and the batch
    replay both call it, so a replayed lock has exactly the effect it has live.
    `min(intended, limit)` is spelled out with Python's tie and NaN rule (the first
    argument unless the second is smaller).
    """
    st[_SOLENOID] = 1.0 if solenoid else 0.0
    st[_ENERGISED] = st[_ENERGISED] + 1.0 if solenoid else 0.0
    cam = st[CAM]
    if st[_LOCKED] != 0.0:
        limit = cam + prm[_ALPHA_MAX]
        hard = intended >= limit - _EPS
        output = limit if limit < intended else intended
        st[OUTPUT] = output
        st[_HARD_STOP] = 1.0 if hard else 0.0
        if output <= cam:
            # The pawl spring pushes the pawl out at alpha = 0.
            st[_LOCKED] = 0.0
            st[_HARD_STOP] = 0.0
            st[CAM] = output
        return
    st[_HARD_STOP] = 0.0
    pawl_on_ratchet = st[_ENERGISED] >= prm[_PULL_IN]
    if pawl_on_ratchet and intended > cam:
        tooth = next_tooth(cam, prm[_PITCH], prm[_PHASE])
        if intended > tooth:
            st[_LOCKED] = 1.0
            st[CAM] = tooth
            limit = tooth + prm[_ALPHA_MAX]
            st[_HARD_STOP] = 1.0 if intended >= limit - _EPS else 0.0
            st[OUTPUT] = limit if limit < intended else intended
            return
    st[OUTPUT] = intended
    st[CAM] = intended


@njit(
    "int64(float64[:, ::1], float64[:, ::1], boolean, boolean, float64, float64)",
    cache=True, nogil=True,
)
def plant_step(
    st: FloatArray, prm: FloatArray, lock_left: bool, lock_right: bool, left: float,
    right: float,
) -> int:
    """Both sides (rows 0 and 1 of `st` and `prm`) one tick; returns the `Status` bits."""
    hip_step(st[0], prm[0], lock_left, left)
    hip_step(st[1], prm[1], lock_right, right)
    status = 0
    if lock_left:
        status |= SOLENOID_LEFT
    if lock_right:
        status |= SOLENOID_RIGHT
    if st[0, _LOCKED] != 0.0:
        status |= LOCKED_LEFT
    if st[1, _LOCKED] != 0.0:
        status |= LOCKED_RIGHT
    if st[0, _HARD_STOP] != 0.0:
        status |= HARD_STOP_LEFT
    if st[1, _HARD_STOP] != 0.0:
        status |= HARD_STOP_RIGHT
    return status


@njit("int64(float64, float64[::1], int64, int64, float64)", cache=True, nogil=True)
def _reading(angle: float, enc: FloatArray, offset: int, direction: int, noise: float) -> int:
    """One encoder's count at link angle `angle`: `EncoderModel.error`, then the noise,
    then `EncoderLayout.count`, in that arithmetic's order."""
    error = enc[_AMP1] * math.sin(angle + enc[_PHASE1]) + enc[_AMP2] * math.sin(
        2.0 * angle + enc[_PHASE2])
    return angle_to_count(angle + error + enc[_NOISE] * noise, offset, direction)


@njit(
    "UniTuple(int64, 4)(float64[:, ::1], float64[:, ::1], int64[:, ::1], float64, float64,"
    " float64, float64)",
    cache=True, nogil=True,
)
def encoder_counts(
    st: FloatArray, enc: FloatArray, layout: npt.NDArray[np.int64], n0: float, n1: float,
    n2: float, n3: float,
) -> tuple[int, int, int, int]:
    """The four encoder counts of the link angles in `st` (rows left, right), for the
    encoder table `enc` (rows in sample order), the layout's (offset, direction) rows
    and the standard normal draws `n0`..`n3`: `ExoPlant.counts` in one compiled call."""
    return (
        _reading(st[0, OUTPUT], enc[0], layout[0, 0], layout[0, 1], n0),
        _reading(st[0, CAM], enc[1], layout[1, 0], layout[1, 1], n1),
        _reading(st[1, OUTPUT], enc[2], layout[2, 0], layout[2, 1], n2),
        _reading(st[1, CAM], enc[3], layout[3, 0], layout[3, 1], n3),
    )


class HipModule:
    """Ratchet, pawl, springs and hard stop of one side. Angles in radians, joint frame.

    The state lives in a float64 row (`state`, see `hip_step`); `ExoPlant` passes a row
    of its own two-side array so that both sides step in one compiled call.
    """

    def __init__(
        self,
        precompression_pct: float = 25.0,
        params: MaccepaParams = PAPER_ACTUATOR,
        tooth_phase: float = 0.0,
        dt: float = SAMPLE_PERIOD_S,
        pull_in_s: float = PULL_IN_S,
        state: FloatArray | None = None,
        constants: FloatArray | None = None,
    ) -> None:
        self.precompression_pct = precompression_pct
        self.params = params
        self.pitch = params.tooth_angle
        self.tooth_phase = tooth_phase
        self.alpha_max = max_deflection(precompression_pct, params)
        self.pull_in_ticks = max(1, round(pull_in_s / dt))
        self.state = np.zeros(N_STATE) if state is None else state
        self.constants = np.zeros(N_PARAMS) if constants is None else constants
        self.constants[:] = (self.pitch, tooth_phase, self.alpha_max, self.pull_in_ticks)
        self.state[:] = 0.0

    def reset(self, angle: float) -> None:
        """Unlocked, both links at `angle`."""
        self.state[:] = 0.0
        self.state[OUTPUT] = self.state[CAM] = angle

    @property
    def output(self) -> float:
        """Output-link angle (follows the thigh, up to the hard stop)."""
        return float(self.state[OUTPUT])

    @property
    def cam(self) -> float:
        """Cam-link angle (grounded at a tooth while locked)."""
        return float(self.state[CAM])

    @property
    def locked(self) -> bool:
        """The pawl holds the ratchet."""
        return bool(self.state[_LOCKED])

    @property
    def hard_stop(self) -> bool:
        """The springs are at their 22 mm compression limit."""
        return bool(self.state[_HARD_STOP])

    @property
    def solenoid(self) -> bool:
        """The last solenoid command."""
        return bool(self.state[_SOLENOID])

    @property
    def alpha(self) -> float:
        """Spring deflection, output minus cam (>= 0)."""
        return float(self.state[OUTPUT] - self.state[CAM])

    def torque(self) -> float:
        """Extension torque of the springs (Nm) at the current deflection."""
        if not self.locked:
            return 0.0
        return maccepa_torque(self.alpha, self.precompression_pct, self.params)

    def next_tooth(self, angle: float) -> float:
        """The first tooth position at or above `angle` in the flexion direction."""
        return float(next_tooth(angle, self.pitch, self.tooth_phase))

    def step(self, solenoid: bool, intended: float) -> None:
        """Advance one tick with the solenoid command and the thigh's intended link angle."""
        hip_step(self.state, self.constants, bool(solenoid), float(intended))


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
        dt: float = SAMPLE_PERIOD_S,
    ) -> None:
        r = np.random.default_rng(np.random.SeedSequence([0x7007, HARDWARE_SEED]))
        phases = r.uniform(0.0, params.tooth_angle, 2)
        #: Both sides' mechanism state and constants, rows (left, right), for `plant_step`.
        self.state = np.zeros((2, N_STATE))
        self.constants = np.zeros((2, N_PARAMS))
        self.left = HipModule(precompression_pct, params, float(phases[0]), dt,
                              state=self.state[0], constants=self.constants[0])
        self.right = HipModule(precompression_pct, params, float(phases[1]), dt,
                               state=self.state[1], constants=self.constants[1])
        self._layout = layout
        self._encoders = encoders if encoders is not None else EncoderModel.from_seed()
        e = self._encoders
        #: The encoders (rows in sample order) and the layout as `encoder_counts` reads them.
        self._encoder_table = np.array(
            [[e.amp1[i], e.phase1[i], e.amp2[i], e.phase2[i], e.noise_rad] for i in range(4)])
        self._layout_table = np.array(
            [[layout.offsets[i], layout.directions[i]] for i in range(4)], dtype=np.int64)

    @property
    def layout(self) -> EncoderLayout:
        """How the encoders are mounted (fixed at construction)."""
        return self._layout

    @property
    def encoders(self) -> EncoderModel:
        """The encoders' non-linearity and noise (fixed at construction)."""
        return self._encoders

    def reset(self, left: float, right: float) -> None:
        """Both sides unlocked at the given link angles."""
        self.left.reset(left)
        self.right.reset(right)

    def step(self, lock_left: bool, lock_right: bool, left: float, right: float) -> Status:
        """Advance both sides one tick; returns the mechanism's status bits."""
        return _STATUS_OF[
            plant_step(self.state, self.constants, bool(lock_left), bool(lock_right),
                       float(left), float(right))
        ]

    def link_angles(self) -> tuple[float, float, float, float]:
        """True (left output, left cam, right output, right cam) angles (rad)."""
        left, right = self.state.tolist()
        return left[OUTPUT], left[CAM], right[OUTPUT], right[CAM]

    def counts(self, noise: Sequence[float]) -> tuple[int, int, int, int]:
        """Encoder readings of the current link angles; `noise` are standard normal draws.

        Per encoder: angle + `EncoderModel.error` + noise level x draw, quantised by the
        layout (`encoder_counts`, compiled: the Python version of these four readings
        cost as much as the rest of a simulated tick)."""
        return encoder_counts(self.state, self._encoder_table, self._layout_table,
                              float(noise[0]), float(noise[1]), float(noise[2]),
                              float(noise[3]))

    def torques(self) -> tuple[float, float]:
        """Exoskeleton extension torque (Nm), left and right."""
        return self.left.torque(), self.right.torque()
