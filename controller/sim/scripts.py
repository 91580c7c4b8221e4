"""Scripts: what the simulated wearer does, in order, and its realisation as a trajectory.

A script is a sequence of steps with timing ranges; realising it for a participant and
a repetition draws every duration, depth and speed, generates the activities and joins
them into one smooth `Trajectory` with ground truth. The built-in scripts follow the
paper's "User study set-up": the squat and stoop sequences (pick up, stand about one
second, put down; five times), a 10 m walk and back, 11 stairs up, a landing turn and 11
down, and the whole evaluation protocol with pauses.

Assumptions: the box is 10 kg in the single sequences (data-collection phase) and 5 kg
in `paper-evaluation` (evaluation phase). In the stoop sequence the feet stay at 90
degrees; the box is picked up in front of one foot and put down in front of the other,
alternating, so five cycles give five stoops to each side. Between trials the wearer
walks a couple of strides to the next station.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controller.device.base import SAMPLE_PERIOD_S
from controller.sim.activities import (
    GaitPiece,
    Segment,
    draw_lift,
    gait,
    lift,
    min_jerk,
    stand,
    walk_amplitude,
)
from controller.sim.activity_kinds import ACTIVITIES
from controller.sim.biomechanics import FloatArray
from controller.sim.participant import VirtualParticipant


@dataclass(frozen=True, slots=True)
class Stand:
    """Stand still for a duration drawn from `seconds` (min, max)."""

    seconds: tuple[float, float]
    holding_box: bool = False


@dataclass(frozen=True, slots=True)
class LiftStep:
    """One lift of `kind`: pick the box up or put it down."""

    kind: str
    pick_up: bool


@dataclass(frozen=True, slots=True)
class GaitStep:
    """A gait bout: pieces of (kind, strides (min, max)) walked without stopping."""

    pieces: tuple[tuple[str, tuple[float, float]], ...]


@dataclass(frozen=True, slots=True)
class HipFlexStep:
    """One hip flexes to `degrees` above standing and back, the other stays still: what an
    experimenter asks for in the hardware bring-up's direction step. Labelled `stand`
    (no lift, no gait); the human moment is left at zero (not used by bring-up)."""

    side: int  # 0 left, 1 right
    degrees: float
    seconds: float  # up and back down


Step = Stand | LiftStep | GaitStep | HipFlexStep


@dataclass(frozen=True, slots=True)
class Script:
    """A named protocol."""

    name: str
    steps: tuple[Step, ...]
    box_kg: float


PAUSE = Stand((6.0, 12.0))
SHORT_WALK = GaitStep((("walk", (1.0, 2.0)),))


def _lift_cycles(kinds: list[tuple[str, str]]) -> tuple[Step, ...]:
    steps: list[Step] = [Stand((3.0, 5.0))]
    for pick, put in kinds:
        steps += [
            LiftStep(pick, True),
            Stand((0.8, 1.3), holding_box=True),
            LiftStep(put, False),
            Stand((1.8, 3.5)),
        ]
    return tuple(steps)


_SQUATS = _lift_cycles([("squat", "squat")] * 5)
_STOOPS = _lift_cycles(
    [("stoop_left", "stoop_right"), ("stoop_right", "stoop_left")] * 2
    + [("stoop_left", "stoop_right")]
)
_WALK = (
    Stand((3.0, 5.0)),
    GaitStep((("walk", (6.5, 7.5)), ("turn", (1.8, 2.4)), ("walk", (6.5, 7.5)))),
    Stand((2.0, 3.0)),
)
_STAIRS = (
    Stand((3.0, 5.0)),
    GaitStep(
        (
            ("walk", (1.0, 2.0)),
            ("stairs_up", (5.5, 5.5)),
            ("turn", (1.8, 2.4)),
            ("stairs_down", (5.5, 5.5)),
            ("walk", (1.0, 1.5)),
        )
    ),
    Stand((2.0, 3.0)),
)

#: Hardware bring-up (docs/hardware-bringup.md): quiet standing for the zero, offset,
#: pulse and watchdog steps, and a single hip flexing for the direction step.
_BRINGUP_STAND = (Stand((30.0, 30.0)),)


def _hip_flex_steps(side: int) -> tuple[Step, ...]:
    # One flexion every 3 s: any capture of 3 s or more holds a whole one.
    return (*(Stand((1.0, 1.0)), HipFlexStep(side, 40.0, 2.0)) * 4, Stand((1.0, 1.0)))


SCRIPTS: dict[str, Script] = {
    "squat-sequence": Script("squat-sequence", _SQUATS, 10.0),
    "stoop-sequence": Script("stoop-sequence", _STOOPS, 10.0),
    "walking": Script("walking", _WALK, 0.0),
    "stairs": Script("stairs", _STAIRS, 0.0),
    "paper-evaluation": Script(
        "paper-evaluation",
        (
            *_SQUATS,
            PAUSE,
            SHORT_WALK,
            *_STOOPS,
            PAUSE,
            SHORT_WALK,
            *_WALK,
            PAUSE,
            SHORT_WALK,
            *_STAIRS,
        ),
        5.0,
    ),
    # The lifts of the paper's evaluation alone (5 kg box): the baseline conditions of a
    # muscle-activity study are measured in lifts only.
    "lift-evaluation": Script("lift-evaluation", (*_SQUATS, PAUSE, SHORT_WALK, *_STOOPS,
                                                   PAUSE), 5.0),
    "standing": Script("standing", _BRINGUP_STAND, 0.0),
    "hip-flex-left": Script("hip-flex-left", _hip_flex_steps(0), 0.0),
    "hip-flex-right": Script("hip-flex-right", _hip_flex_steps(1), 0.0),
}
SCRIPT_NAMES: tuple[str, ...] = tuple(SCRIPTS)


def get_script(name: str) -> Script:
    """The built-in script called `name`."""
    try:
        return SCRIPTS[name]
    except KeyError:
        raise ValueError(
            f"unknown script {name!r}; choose one of {', '.join(SCRIPT_NAMES)}"
        ) from None


@dataclass(frozen=True)
class Trajectory:
    """One realisation of a script: true hip flexion (rad), human hip extension moments
    (Nm) and ground truth at `t` (s, absolute, step SAMPLE_PERIOD_S)."""

    t: FloatArray  # (K,)
    theta: FloatArray  # (K, 2)
    torque: FloatArray  # (K, 2)
    activity: NDArray[np.int8]  # (K,) codes into ACTIVITIES
    lift: NDArray[np.int32]  # (K,) lift index through the script (offset included), -1
    progress: FloatArray  # (K,)
    n_lifts: int

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def duration(self) -> float:
        """Seconds covered, n * SAMPLE_PERIOD_S."""
        return self.n * SAMPLE_PERIOD_S

    def activity_names(self) -> NDArray[np.str_]:
        """Activity labels as strings."""
        return np.asarray(ACTIVITIES)[self.activity]


def _stride_s(p: VirtualParticipant, kind: str, rng: np.random.Generator) -> float:
    base = {
        "walk": p.stride_s,
        "turn": 1.15 * p.stride_s,
        "stairs_up": p.stair_stride_s,
        "stairs_down": 0.9 * p.stair_stride_s,
    }[kind]
    return base * float(1.0 + np.clip(rng.normal(0.0, 0.03), -0.08, 0.08))


def _gait_pieces(
    p: VirtualParticipant, step: GaitStep, rng: np.random.Generator
) -> list[GaitPiece]:
    pieces = []
    walk_amp = walk_amplitude(p) * float(1.0 + np.clip(rng.normal(0, 0.04), -0.1, 0.1))
    for kind, (lo, hi) in step.pieces:
        strides = float(rng.uniform(lo, hi))
        if kind == "walk":
            amp = (walk_amp, walk_amp)
        elif kind == "turn":
            outer = float(rng.uniform(0.55, 0.65)) * walk_amp
            inner = float(rng.uniform(0.45, 0.55)) * walk_amp
            amp = (outer, inner) if rng.random() < 0.5 else (inner, outer)
        else:
            a = float(1.0 + np.clip(rng.normal(0.0, 0.04), -0.1, 0.1))
            amp = (a * (1.0 + p.asymmetry / 2.0), a * (1.0 - p.asymmetry / 2.0))
        pieces.append(GaitPiece(kind, strides, _stride_s(p, kind, rng), amp))
    return pieces


def _hip_flex(p: VirtualParticipant, step: HipFlexStep, moments: bool = True) -> Segment:
    """One hip up by `step.degrees` and back (minimum jerk each way), the other standing."""
    n = max(2, round(step.seconds / SAMPLE_PERIOD_S))
    half = np.linspace(0.0, 2.0, n)
    shape = np.where(half <= 1.0, min_jerk(half), min_jerk(2.0 - half))
    theta = np.tile(p.stand_flexion, (n, 1))
    theta[:, step.side] += np.radians(step.degrees) * shape
    stand_code = ACTIVITIES.index("stand")
    torque = np.zeros((n, 2)) if moments else np.full((n, 2), np.nan)
    return Segment(theta, torque, np.full(n, stand_code, dtype=np.int8),
                   np.full(n, -1, dtype=np.int32), np.full(n, np.nan))


def realise(
    script: Script,
    participant: VirtualParticipant,
    seed: int,
    repetition: int = 0,
    t0: float = 0.0,
    lift_offset: int = 0,
    *,
    moments: bool = True,
) -> Trajectory:
    """Draw one realisation of `script` (deterministic in seed and repetition), starting
    at absolute time `t0` and numbering lifts from `lift_offset`. `moments=False` leaves
    the hip moments out (`torque` NaN) for callers that only need the angles (a cohort's
    replay): the same draws and angles, at well under half the cost."""
    rng = np.random.default_rng(np.random.SeedSequence([0x5C_21, int(seed), int(repetition)]))
    p = participant
    segments: list[Segment] = []
    lift_ids: list[int] = []
    n_lifts = 0
    for step in script.steps:
        if isinstance(step, Stand):
            box = script.box_kg if step.holding_box else 0.0
            seg = stand(p, float(rng.uniform(*step.seconds)), box, moments=moments)
            lift_ids.append(-1)
        elif isinstance(step, HipFlexStep):
            seg = _hip_flex(p, step, moments)
            lift_ids.append(-1)
        elif isinstance(step, LiftStep):
            shape = draw_lift(p, rng, step.kind)
            seg = lift(p, shape, script.box_kg, step.pick_up, moments=moments)
            lift_ids.append(lift_offset + n_lifts)
            n_lifts += 1
        else:
            lead = "left" if rng.random() < 0.5 else "right"
            seg = gait(p, _gait_pieces(p, step, rng), lead, moments=moments)
            lift_ids.append(-1)
        segments.append(seg)
    n = sum(s.n for s in segments)
    t: FloatArray = (t0 + np.arange(n) * SAMPLE_PERIOD_S).astype(np.float64)
    theta = np.concatenate([s.theta for s in segments]) + p.sway(t)
    lift_idx = np.concatenate(
        [
            np.where(s.lift >= 0, i, -1).astype(np.int32)
            for s, i in zip(segments, lift_ids, strict=True)
        ]
    )
    return Trajectory(
        t=t,
        theta=theta,
        torque=np.concatenate([s.torque for s in segments]),
        activity=np.concatenate([s.activity for s in segments]),
        lift=lift_idx,
        progress=np.concatenate([s.progress for s in segments]),
        n_lifts=n_lifts,
    )
