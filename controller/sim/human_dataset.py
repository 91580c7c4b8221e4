"""The built-in reference human dataset: mean hip angle and moment over progress.

The paper computes its utilities from the mean trajectories of a lab dataset (Van der
Have et al.); without one, this module averages the simulated wearer over a virtual
cohort instead, with the same generators the simulator uses. Assumptions:
- Lifts are pick-ups (lowering empty-handed, raising with the box, 10 kg by default),
  from onset to the return to standing, time-normalised over their own duration.
- Walking is one steady gait cycle from left heel strike (no sway, no initiation).
- Angles are the true hip flexion (no exoskeleton offset, no sensor noise).
The version names the generator: it hashes the source of every module that shapes the
data together with the parameters, so any change to the generator gives a new version.

Regenerate with `write_reference_dataset(path)`.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
from pathlib import Path
from types import ModuleType

import numpy as np

from controller.human_data import HUMAN_MOTIONS, N_PROGRESS, HumanMotionData
from controller.sim import activities, biomechanics, participant
from controller.sim.activities import GaitPiece, draw_lift, gait_cycle_values, lift, walk_amplitude
from controller.sim.participant import VirtualParticipant

#: 2: per-leg moments from the stance geometry (no `box_side_share`), squat box clear
#: of the knees. 3: squats with lumbar flexion and moving hips (Newton-Euler).
GENERATOR_VERSION = "3"
DEFAULT_PARTICIPANTS = 24
DEFAULT_REPETITIONS = 5
DEFAULT_BOX_KG = 10.0


def cohort(seed: int, n: int) -> list[VirtualParticipant]:
    """The `n` virtual participants of cohort `seed` (deterministic)."""
    states = np.random.SeedSequence([0xC0_4027, int(seed)]).generate_state(n)
    return [VirtualParticipant.from_seed(int(s)) for s in states]


def generator_version(**params: object) -> str:
    """Version string of the generator with these parameters."""
    h = hashlib.sha256()
    h.update(_generator_source())
    h.update(json.dumps(params, sort_keys=True).encode())
    return f"sim-{GENERATOR_VERSION}+{h.hexdigest()[:12]}"


@functools.cache
def _generator_source() -> bytes:
    """The source the data depends on, read once per process (a process runs one
    version of its code)."""
    modules: tuple[ModuleType, ...] = (participant, biomechanics, activities)
    return b"".join([*(inspect.getsource(mod).encode() for mod in modules),
                     inspect.getsource(_compute).encode()])


def reference_version(seed: int = 0, participants: int = DEFAULT_PARTICIPANTS,
                      repetitions: int = DEFAULT_REPETITIONS,
                      box_kg: float = DEFAULT_BOX_KG) -> str:
    """The version `reference_dataset` with these arguments would carry, without
    computing the data (0.2-0.3 s of CPU): a cache of data derived from it (the default
    utilities, checked at every server start) is checked against this."""
    return generator_version(seed=seed, participants=participants,
                             repetitions=repetitions, box_kg=box_kg)


def _compute(
    people: list[VirtualParticipant], seed: int, repetitions: int, box_kg: float
) -> tuple[np.ndarray, np.ndarray]:
    grid = np.linspace(0.0, 1.0, N_PROGRESS)
    theta = np.zeros((len(HUMAN_MOTIONS), 2, N_PROGRESS))
    tau = np.zeros_like(theta)
    rng = np.random.default_rng(np.random.SeedSequence([0xDA7A, int(seed)]))
    for p in people:
        for m, motion in enumerate(HUMAN_MOTIONS):
            if motion == "walking":
                piece = GaitPiece("walk", 1.0, p.stride_s, (walk_amplitude(p),) * 2)
                dth, mom = gait_cycle_values(p, piece, grid)
                theta[m] += (p.stand_flexion[None, :] + dth).T
                tau[m] += mom.T
                continue
            for _ in range(repetitions):
                seg = lift(p, draw_lift(p, rng, motion), box_kg, pick_up=True)
                prog = np.linspace(0.0, 1.0, seg.n)
                for leg in range(2):
                    theta[m, leg] += np.interp(grid, prog, seg.theta[:, leg]) / repetitions
                    tau[m, leg] += np.interp(grid, prog, seg.torque[:, leg]) / repetitions
    return theta / len(people), tau / len(people)


def reference_dataset(
    seed: int = 0,
    participants: int = DEFAULT_PARTICIPANTS,
    repetitions: int = DEFAULT_REPETITIONS,
    box_kg: float = DEFAULT_BOX_KG,
) -> HumanMotionData:
    """Mean hip flexion (rad) and hip extension moment (Nm) per motion and leg over
    progress, averaged over a virtual cohort. Same arguments, same data."""
    if participants < 1 or repetitions < 1:
        raise ValueError("need at least one participant and one repetition")
    if box_kg < 0:
        raise ValueError("box mass cannot be negative")
    people = cohort(seed, participants)
    theta, tau = _compute(people, seed, repetitions, box_kg)
    params = {"seed": seed, "participants": participants, "repetitions": repetitions,
              "box_kg": box_kg}
    return HumanMotionData(
        theta=theta,
        tau=tau,
        source="simulated: controller.sim.human_dataset",
        version=reference_version(seed, participants, repetitions, box_kg),
        meta={
            **params,
            "generator": "controller.sim.human_dataset.reference_dataset",
            "mean_mass_kg": round(float(np.mean([p.mass_kg for p in people])), 2),
            "mean_height_m": round(float(np.mean([p.height_m for p in people])), 3),
            "lifts": "pick-up: lowering without the box, raising with it",
            "walking": "one steady gait cycle from left heel strike",
            "leg_split": "statics of the task's geometry (controller.sim.biomechanics)",
        },
    )


def write_reference_dataset(path: Path | str, seed: int = 0) -> HumanMotionData:
    """Generate the reference dataset and save it as JSON at `path` (for a CLI command)."""
    data = reference_dataset(seed=seed)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    data.save(out)
    return data
