"""Automatic lift segmentation of stored ticks, for recordings and trials alike.

The experimenter's starting point for the ground truth: the lifts found in the hip
angles, each labelled with the simulation's activity at its peak where the ticks carry
one (hardware ticks do not: those segments are "unlabelled" until the experimenter
labels them).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from controller.device.base import SAMPLE_PERIOD_S
from controller.intent.segmentation import bridge_gaps, segment_lifts
from controller.tick_record import MODEL_NAMES

#: Fewer samples than this (one second at the 100 Hz sample clock) cannot hold a lift.
MIN_SAMPLES = 100


class SegmentationError(ValueError):
    """Why the ticks cannot be segmented: `too_short` (with the sample count) or
    `no_angles` (no valid hip angle at all)."""

    def __init__(self, reason: str, samples: int) -> None:
        super().__init__(f"{reason} ({samples} samples)")
        self.reason, self.samples = reason, samples


@dataclass(frozen=True)
class ProposedLift:
    """A lift found automatically: sample indices from the first tick, and a label."""

    start: int
    peak: int
    end: int
    label: str


def propose_lifts(cols: Mapping[str, np.ndarray]) -> list[ProposedLift]:
    """The lifts in columns holding `q_left`, `q_right` and `truth_activity`."""
    q = np.column_stack([cols["q_left"], cols["q_right"]]).astype(np.float64)
    if q.shape[0] < MIN_SAMPLES:
        raise SegmentationError("too_short", q.shape[0])
    if np.isnan(q).all():
        raise SegmentationError("no_angles", q.shape[0])
    try:
        q = bridge_gaps(q)
    except ValueError as exc:
        raise SegmentationError("no_angles", q.shape[0]) from exc
    # The sample clock, not the device's timestamps, which restart if the device restarts
    # mid-run.
    found = segment_lifts(np.arange(q.shape[0], dtype=np.float64) * SAMPLE_PERIOD_S, q)
    truth = cols["truth_activity"]
    out = []
    for seg in found:
        label = str(truth[seg.peak])
        out.append(ProposedLift(seg.start, seg.peak, seg.end,
                                label if label in MODEL_NAMES else "unlabelled"))
    return out
