"""Activities of the simulated wearer: hip flexion and hip moments over time, vectorised.

Each generator returns a `Segment`: true hip flexion (rad, flexion positive) and hip
extension moment (Nm) per leg at 100 Hz, with the ground-truth labels. Segments start
and end at the participant's standing posture with zero velocity and acceleration, so
that a script is a smooth concatenation (the controllers differentiate the angles).
Postural sway is added by the script over the whole timeline.

Kinematic assumptions (the project's own, against `docs/simulated-wearer.md`):
- Lifts: minimum-jerk lowering (1.1-1.45 s at nominal speed), a 0.25-0.55 s pause at
  the bottom (grasp or release), minimum-jerk raising (0.95-1.15 x the lowering time).
  Peak hip velocity is 1.875 x range / duration, i.e. 2-3 rad/s.
- Squat: both hips to the participant's depth (92-108 deg); the pelvis tilts by a fixed
  fraction (0.36-0.48) of hip flexion and the lumbar spine flexes on top of it
  (`biomechanics.squat_pose`). Asymmetric stoop: the box-side hip to 76-94 deg,
  the other hip to 0.62-0.78 of it (the feet are at 90 degrees, so the trunk's bend is
  partly rotation and abduction for that hip); the trunk inclines 0.95 x the box-side
  hip flexion (lumbar flexion compensates the thighs' backward tilt).
- Hip moments per leg come from `controller.sim.biomechanics`: half each in a squat,
  from the stance geometry in an asymmetric stoop (no free share parameter).
- Gait: one periodic template per kind over the leg's own cycle (0 = foot contact), the
  right leg half a cycle after the left; amplitude ramps in over the first 0.6 stride
  (gait initiation) and out over the last; kinds cross-fade over 0.8 s (a
  shorter fade between templates as different as walking and stairs would add
  unphysical hip velocity).
- Turns: the walking template at 45-65 % amplitude, the inner leg smaller, slower strides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from controller.device.base import SAMPLE_PERIOD_S
from controller.sim.activity_kinds import ACTIVITY_CODE, GAIT_KINDS, LIFT_KINDS
from controller.sim.biomechanics import (
    Anthropometrics,
    FloatArray,
    gait_moment,
    lift_hip_moment,
    split_moment,
    squat_pose,
    stoop_leg_moments,
    top_down_hip_moment,
)
from controller.sim.participant import VirtualParticipant

STOOP_TRUNK_RATIO = 0.95
CROSS_FADE_S = 0.8
RAMP_STRIDES = 0.6
BOX_TRANSFER_S = 0.25  # the box's weight moves onto or off the hands over this time


@dataclass(frozen=True)
class Segment:
    """A stretch of samples at 100 Hz. `lift` is 0 inside the segment's lift, -1 else
    (the script numbers lifts); `progress` is NaN outside lifts."""

    theta: FloatArray  # (K, 2) rad
    torque: FloatArray  # (K, 2) Nm, hip extension positive
    activity: NDArray[np.int8]  # (K,) codes into ACTIVITIES
    lift: NDArray[np.int32]  # (K,)
    progress: FloatArray  # (K,)

    def __post_init__(self) -> None:
        k = self.theta.shape[0]
        if self.theta.shape != (k, 2) or self.torque.shape != (k, 2):
            raise ValueError("theta and torque must have shape (K, 2)")
        if not (self.activity.shape == self.lift.shape == self.progress.shape == (k,)):
            raise ValueError("labels must have shape (K,)")

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.theta.shape[0])


def min_jerk(x: npt.ArrayLike) -> FloatArray:
    """0 -> 1 with zero velocity and acceleration at both ends (x clipped to 0..1)."""
    u = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.asarray(u * u * u * (10.0 - 15.0 * u + 6.0 * u * u), dtype=np.float64)


def _n_samples(duration: float) -> int:
    return max(2, math.ceil(duration / SAMPLE_PERIOD_S - 1e-9) + 1)


def _labels(n: int, activity: str, in_lift: bool) -> tuple[NDArray[np.int8], NDArray[np.int32]]:
    act = np.full(n, ACTIVITY_CODE[activity], dtype=np.int8)
    lift = np.full(n, 0 if in_lift else -1, dtype=np.int32)
    return act, lift


def _no_moments(n: int) -> FloatArray:
    """The torque of a segment generated without hip moments (`moments=False`): NaN, so
    that nothing can mistake it for a computed moment."""
    return np.full((n, 2), np.nan)


def _vary(rng: np.random.Generator, sd: float) -> float:
    """A multiplicative repetition factor, truncated at 2 SD."""
    return float(1.0 + np.clip(rng.normal(0.0, sd), -2.0 * sd, 2.0 * sd))


def stand(
    p: VirtualParticipant, duration: float, box_kg: float = 0.0, *, moments: bool = True
) -> Segment:
    """Quiet standing (optionally holding the box against the body). `moments=False`
    skips the hip moments (torque NaN): the angles alone cost a fraction of them."""
    n = _n_samples(duration)
    theta = np.tile(p.stand_flexion, (n, 1))
    if moments:
        body = Anthropometrics.from_body(p.mass_kg, p.height_m)
        total = lift_hip_moment(body, np.zeros(n), np.full(n, box_kg), SAMPLE_PERIOD_S)
        torque = split_moment(total, 0.5)  # feet parallel, load on the midline
    else:
        torque = _no_moments(n)
    act, lift = _labels(n, "stand", False)
    return Segment(theta, torque, act, lift, np.full(n, np.nan))


@dataclass(frozen=True, slots=True)
class LiftShape:
    """The drawn parameters of one lift (kept so tests and datasets can inspect them)."""

    kind: str
    peak_deg: tuple[float, float]  # absolute peak hip flexion, left/right
    t_down: float
    t_pause: float
    t_up: float
    lag_s: tuple[float, float] = (0.0, 0.0)  # delay of each hip's motion (one is 0)

    @property
    def duration(self) -> float:
        """Onset to return to standing (s), including the lagging hip."""
        return self.t_down + self.t_pause + self.t_up + max(self.lag_s)

    def profile(self, t: FloatArray, leg: int) -> FloatArray:
        """Fraction of the way to the peak (0..1) of hip `leg` at times `t`."""
        u = t - self.lag_s[leg]
        t_bottom = self.t_down + self.t_pause
        return np.where(
            u <= self.t_down,
            min_jerk(u / self.t_down),
            1.0 - min_jerk((u - t_bottom) / self.t_up),
        )


def draw_lift(p: VirtualParticipant, rng: np.random.Generator, kind: str) -> LiftShape:
    """Depth and timing of one repetition of `kind` for participant `p`."""
    if kind not in LIFT_KINDS:
        raise ValueError(f"unknown lift {kind!r}; choose one of {', '.join(LIFT_KINDS)}")
    f = p.rep_variation
    depth = _vary(rng, 0.6 * f)  # depth is more consistent than timing
    speed = p.speed * _vary(rng, 1.5 * f)
    t_down = float(rng.uniform(1.1, 1.45)) / speed
    t_pause = float(rng.uniform(0.25, 0.55))
    t_up = t_down * float(rng.uniform(0.95, 1.15))
    asym = p.asymmetry + float(np.clip(rng.normal(0.0, 0.015), -0.045, 0.045))
    if kind == "squat":
        peak = p.squat_depth_deg * depth
        left, right = peak * (1.0 + asym / 2.0), peak * (1.0 - asym / 2.0)
    else:
        box_side = p.stoop_depth_deg * depth
        other = box_side * p.stoop_other_ratio * _vary(rng, f)
        left, right = (box_side, other) if kind == "stoop_left" else (other, box_side)
    # The hips do not start together: in a squat either may lead by a few tens of ms;
    # in a stoop the hip away from the box follows the trunk's turn a little later.
    if kind == "squat":
        lag = float(np.clip(abs(rng.normal(0.0, 0.02)), 0.0, 0.05))
        lags = (lag, 0.0) if rng.random() < 0.5 else (0.0, lag)
    else:
        lag = float(rng.uniform(0.0, 0.08))
        lags = (0.0, lag) if kind == "stoop_left" else (lag, 0.0)
    return LiftShape(kind, (float(left), float(right)), t_down, t_pause, t_up, lags)


def lift(
    p: VirtualParticipant, shape: LiftShape, box_kg: float, pick_up: bool, *,
    moments: bool = True,
) -> Segment:
    """One lift from standing to standing: pick the box up (`pick_up`) or put it down.

    Progress runs 0..1 over the whole segment, so the hip-flexion half is about its
    first 40-45 %. The box weighs on the hands after lift-off when picking up, until
    touch-down when putting down. `moments=False` skips the hip moments (torque NaN).
    """
    n = _n_samples(shape.duration)
    t = (np.arange(n) * SAMPLE_PERIOD_S).astype(np.float64)
    s = np.stack([shape.profile(t, 0), shape.profile(t, 1)], axis=1)
    stand_flex = p.stand_flexion
    delta = np.radians(np.asarray(shape.peak_deg)) - stand_flex
    theta = stand_flex[None, :] + s * delta[None, :]
    torque = (_lift_moments(p, shape, box_kg, pick_up, t, s, delta) if moments
              else _no_moments(n))
    act, lift_idx = _labels(n, shape.kind, True)
    progress = np.clip(t / shape.duration, 0.0, 1.0)
    return Segment(theta, torque, act, lift_idx, progress)


def _lift_moments(
    p: VirtualParticipant, shape: LiftShape, box_kg: float, pick_up: bool, t: FloatArray,
    s: FloatArray, delta: FloatArray,
) -> FloatArray:
    """The hip extension moments (K, 2) of one lift, from its profile `s` (fraction of
    the way to the peak per hip) and `delta` (peak minus standing flexion, rad)."""
    if shape.kind == "squat":
        ref = int(np.argmin(shape.lag_s))
    else:
        ref = 0 if shape.kind == "stoop_left" else 1
        trunk = STOOP_TRUNK_RATIO * s[:, ref] * float(delta[ref])
    u = t - shape.lag_s[ref]
    if pick_up:
        t_liftoff = shape.t_down + shape.t_pause
        held = min_jerk((u - (t_liftoff - BOX_TRANSFER_S)) / BOX_TRANSFER_S)
    else:
        held = 1.0 - min_jerk((u - shape.t_down) / BOX_TRANSFER_S)
    body = Anthropometrics.from_body(p.mass_kg, p.height_m)
    if shape.kind == "squat":
        # Feet parallel, load on the midline: each hip half. The hips move down and
        # back, the thorax leans by the pelvis' tilt plus lumbar flexion (biomechanics).
        pose = squat_pose(body, s @ delta / 2.0, p.squat_pelvis_ratio, box_kg * held)
        total = top_down_hip_moment(
            body, pose.trunk, pose.hip, pose.box, box_kg * held, SAMPLE_PERIOD_S
        )
        torque = split_moment(total, 0.5)
    else:
        # The box stands where the hands reach it at the bottom of the bend.
        bottom = np.array([STOOP_TRUNK_RATIO * float(delta[ref])])
        reach = float(body.box_distance(bottom)[0])
        torque = stoop_leg_moments(body, trunk, box_kg * held, SAMPLE_PERIOD_S, ref, reach)
    return torque


def _periodic_deg(points: list[tuple[float, float]]) -> CubicSpline:
    x = np.array([q[0] for q in points] + [1.0])
    y = np.radians(np.array([q[1] for q in points] + [points[0][1]]))
    return CubicSpline(x, y, bc_type="periodic")


# Hip flexion over the leg's own cycle, degrees above the standing posture.
GAIT_ANGLE: dict[str, CubicSpline] = {
    # Level walking: about +32 at contact and late swing, -11 in late stance (range 43).
    "walk": _periodic_deg(
        [(0.00, 28.0), (0.10, 25.0), (0.30, 6.0), (0.50, -11.0), (0.60, -6.0),
         (0.75, 16.0), (0.87, 32.0), (0.95, 30.0)]
    ),
    # Stair ascent: the foot lands on the next step with the hip at about 60 deg and the
    # stance leg pulls the body up to about 3 deg (range ~58); swing flexes it again.
    "stairs_up": _periodic_deg(
        [(0.00, 58.0), (0.10, 52.0), (0.30, 28.0), (0.50, 8.0), (0.60, 3.0),
         (0.68, 7.0), (0.78, 27.0), (0.88, 51.0), (0.96, 60.0)]
    ),
    # Stair descent: range about 28 deg, most flexion late in stance and in swing.
    "stairs_down": _periodic_deg(
        [(0.00, 10.0), (0.15, 6.0), (0.35, 7.0), (0.55, 16.0), (0.68, 28.0),
         (0.82, 34.0), (0.92, 22.0)]
    ),
}
GAIT_ANGLE["turn"] = GAIT_ANGLE["walk"]


@dataclass(frozen=True, slots=True)
class GaitPiece:
    """Part of a gait bout: `strides` cycles of one kind at amplitude (left, right)
    relative to the participant's template, each stride lasting `stride_s`."""

    kind: str
    strides: float
    stride_s: float
    amplitude: tuple[float, float] = (1.0, 1.0)

    def __post_init__(self) -> None:
        if self.kind not in GAIT_KINDS:
            raise ValueError(f"unknown gait {self.kind!r}; choose one of {GAIT_KINDS}")
        if self.strides <= 0 or self.stride_s <= 0:
            raise ValueError("strides and stride_s must be positive")


def _moment_kind(kind: str) -> tuple[str, float]:
    # A turn's hip moments: the walking curve, reduced like its angles.
    return ("walk", 0.7) if kind == "turn" else (kind, 1.0)


def gait_cycle_values(
    p: VirtualParticipant, piece: GaitPiece, phase_left: FloatArray, *, moments: bool = True
) -> tuple[FloatArray, FloatArray]:
    """Steady-state hip flexion above standing (rad) and hip moment (Nm), shape (K, 2),
    of `piece` at the left leg's gait phase; the right leg is half a cycle later.
    `moments=False` skips the moments (NaN)."""
    kind, moment_scale = _moment_kind(piece.kind)
    dtheta = np.empty((phase_left.size, 2))
    moment = np.empty((phase_left.size, 2)) if moments else _no_moments(phase_left.size)
    for leg in range(2):
        frac = np.mod(phase_left + 0.5 * leg, 1.0)
        amp = piece.amplitude[leg]
        dtheta[:, leg] = amp * GAIT_ANGLE[piece.kind](frac)
        if moments:
            moment[:, leg] = gait_moment(kind, frac, p.mass_kg,
                                         p.torque_scale * moment_scale * amp)
    return dtheta, moment


def gait(p: VirtualParticipant, pieces: list[GaitPiece], lead: str = "left", *,
         moments: bool = True) -> Segment:
    """A continuous gait bout from standing to standing through the given pieces; the
    `lead` leg takes the first step (its swing comes first). `moments=False` skips the
    hip moments (torque NaN)."""
    if lead not in ("left", "right"):
        raise ValueError(f"lead must be 'left' or 'right', got {lead!r}")
    if not pieces:
        raise ValueError("a gait bout needs at least one piece")
    durations = np.array([pc.strides * pc.stride_s for pc in pieces])
    bounds = np.concatenate([[0.0], np.cumsum(durations)])
    total = float(bounds[-1])
    n = _n_samples(total)
    t = np.arange(n) * SAMPLE_PERIOD_S
    # Smooth partition of unity over the pieces.
    h = [np.ones(n)] + [min_jerk((t - b) / CROSS_FADE_S + 0.5) for b in bounds[1:-1]]
    h.append(np.zeros(n))
    weights = [h[i] - h[i + 1] for i in range(len(pieces))]
    freq = np.zeros(n)
    for w, pc in zip(weights, pieces, strict=True):
        freq += w / pc.stride_s
    start = 0.5 if lead == "left" else 0.0  # phase 0.5: the leg is about to swing
    phase_left = start + np.concatenate([[0.0], np.cumsum(freq[:-1]) * SAMPLE_PERIOD_S])
    ramp_in = RAMP_STRIDES * pieces[0].stride_s
    ramp_out = RAMP_STRIDES * pieces[-1].stride_s
    env = min_jerk(t / ramp_in) * (1.0 - min_jerk((t - (total - ramp_out)) / ramp_out))
    theta = np.tile(p.stand_flexion, (n, 1))
    torque = np.zeros((n, 2)) if moments else _no_moments(n)
    for w, pc in zip(weights, pieces, strict=True):
        dtheta, moment = gait_cycle_values(p, pc, phase_left, moments=moments)
        theta += (env * w)[:, None] * dtheta
        if moments:
            torque += (env * w)[:, None] * moment
    which = np.clip(np.searchsorted(bounds, t, side="right") - 1, 0, len(pieces) - 1)
    codes = np.array([ACTIVITY_CODE[pc.kind] for pc in pieces], dtype=np.int8)
    act = codes[which]
    return Segment(theta, torque, act, np.full(n, -1, dtype=np.int32), np.full(n, np.nan))


def walk_amplitude(p: VirtualParticipant) -> float:
    """Template scale that gives the participant's walking range (template range 43)."""
    return p.walk_range_deg / 43.0
