"""The data-collection phase in simulation: virtual participants demonstrate lifts while
wearing the (unlocked) exoskeleton, and motion models are fitted from what the encoders saw.

As in the paper, demonstrations are the exoskeleton's own measurements (with each
donning's offsets and the encoders' noise), segmented automatically. Where a lab's
experimenter would label each segment, the simulation uses its ground truth: the
activity at the segment's peak. Segments whose peak is not a lift are discarded and
counted, so a segmentation that goes wrong shows up in the provenance.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from controller.intent.motion_model import ModelSet, fit_model_set
from controller.intent.segmentation import SegmentedLift, segment_lifts
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout
from controller.sim.exoskeleton import SimulatedExoskeleton
from controller.tick_record import MODEL_NAMES

FloatArray = NDArray[np.float64]
DEMO_SCRIPTS: tuple[str, ...] = ("squat-sequence", "stoop-sequence")


@dataclass(frozen=True)
class SimulatedRecording:
    """A continuous measured recording with its ground truth, one row per 10 ms sample."""

    seed: int
    script: str
    t: FloatArray
    q: FloatArray  # (K, 2) measured hip flexion (rad)
    activity: tuple[str, ...]
    lift: NDArray[np.int64]


@dataclass
class Demonstrations:
    """Labelled lift segments, ready for `fit_model_set`."""

    segments: dict[str, list[FloatArray]] = field(default_factory=dict)
    ids: dict[str, list[str]] = field(default_factory=dict)
    discarded: int = 0


def record(seed: int, script: str, layout: EncoderLayout = DEFAULT_LAYOUT) -> SimulatedRecording:
    """Run one script with no lock commands and decode what the encoders measured."""
    exo = SimulatedExoskeleton(seed=seed, script=script, layout=layout, loop=False)
    n = round(exo.duration / exo.dt)
    t = np.empty(n)
    q = np.empty((n, 2))
    activity: list[str] = []
    lift = np.empty(n, dtype=np.int64)
    for k in range(n):
        s = exo.tick(None)
        ql, _, qr, _ = layout.joint_angles(s.counts)
        t[k], q[k, 0], q[k, 1] = s.t, ql, qr
        activity.append(s.truth.activity if s.truth else "")
        lift[k] = s.truth.lift_index if s.truth else -1
    return SimulatedRecording(seed, script, t, q, tuple(activity), lift)


def label_segments(
    rec: SimulatedRecording, segments: Sequence[SegmentedLift]
) -> list[tuple[str, SegmentedLift]]:
    """Label each segment with the true activity at its peak; drop non-lifts."""
    out = []
    for seg in segments:
        label = rec.activity[seg.peak]
        if label in MODEL_NAMES:
            out.append((label, seg))
    return out


def collect(
    seeds: Sequence[int],
    scripts: Sequence[str] = DEMO_SCRIPTS,
    progress: Callable[[float], None] | None = None,
) -> Demonstrations:
    """Record every participant in every script and keep the labelled lifts."""
    demos = Demonstrations({m: [] for m in MODEL_NAMES}, {m: [] for m in MODEL_NAMES})
    total = len(seeds) * len(scripts)
    done = 0
    for seed in seeds:
        for script in scripts:
            rec = record(seed, script)
            segs = segment_lifts(rec.t, rec.q)
            labelled = label_segments(rec, segs)
            demos.discarded += len(segs) - len(labelled)
            for i, (label, seg) in enumerate(labelled):
                demos.segments[label].append(rec.q[seg.start : seg.end + 1].copy())
                demos.ids[label].append(f"sim:seed={seed}:{script}:segment={i}")
            done += 1
            if progress is not None:
                progress(done / total)
    return demos


def simulated_model_set(
    seeds: Sequence[int] = (101, 102, 103, 104, 105, 106),
    progress: Callable[[float], None] | None = None,
) -> ModelSet:
    """Models fitted from virtual participants' demonstrations (the paper had 6)."""
    demos = collect(seeds, progress=progress)
    missing = [m for m in MODEL_NAMES if len(demos.segments[m]) < 2]
    if missing:
        raise ValueError(f"too few demonstrations found for {missing}; check segmentation")
    return fit_model_set(
        demos.segments,
        version=f"sim-{'-'.join(str(s) for s in seeds)}",
        demo_ids=demos.ids,
        meta={"source": "simulated data collection", "seeds": list(seeds),
              "scripts": list(DEMO_SCRIPTS), "discarded_segments": demos.discarded},
    )
