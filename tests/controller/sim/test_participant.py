"""Virtual participants: reproducible from a seed, varied across seeds, plausible bodies."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from controller.sim.participant import VirtualParticipant


def test_same_seed_same_participant_and_different_seeds_differ() -> None:
    assert VirtualParticipant.from_seed(7) == VirtualParticipant.from_seed(7)
    a, b = VirtualParticipant.from_seed(7), VirtualParticipant.from_seed(8)
    assert a != b
    assert (a.mass_kg, a.height_m, a.squat_depth_deg) != (b.mass_kg, b.height_m, b.squat_depth_deg)


def test_cohort_is_plausible_and_varied() -> None:
    people = [VirtualParticipant.from_seed(s) for s in range(60)]
    mass = np.array([p.mass_kg for p in people])
    height = np.array([p.height_m for p in people])
    assert mass.min() > 45 and mass.max() < 125
    assert height.min() > 1.5 and height.max() < 2.0
    assert 60 < mass.mean() < 85 and mass.std() > 5
    assert {p.sex for p in people} == {"male", "female"}
    assert all(1.0 <= p.stride_s <= 1.2 for p in people)
    assert np.std([p.speed for p in people]) > 0.05
    assert np.std([p.asymmetry for p in people]) > 0.01


def test_donning_offsets_are_several_degrees_and_change_per_donning() -> None:
    offsets = np.array([VirtualParticipant.from_seed(s).offset_deg for s in range(80)])
    assert np.abs(offsets).max() <= 7.0
    assert 2.0 < offsets.std() < 4.5  # several degrees per encoder
    p = VirtualParticipant.from_seed(3)
    q = p.donned(1)
    assert q.offset_deg != p.offset_deg
    assert (q.mass_kg, q.height_m, q.sex) == (p.mass_kg, p.height_m, p.sex)
    assert p.donned(1) == q


def test_offset_drifts_slowly_from_the_donning_offset() -> None:
    p = VirtualParticipant.from_seed(11)
    t = np.arange(0.0, 600.0, 0.01)
    off = np.degrees(p.encoder_offset(t))
    assert off[0] == pytest.approx(p.offset_deg, abs=1e-9)
    drift = off - np.asarray(p.offset_deg)
    assert np.abs(drift).max() <= 2.5
    assert np.abs(drift).max() > 0.2  # it does drift
    rate = np.abs(np.diff(off, axis=0)).max() / 0.01  # deg/s
    assert rate < 0.05


def test_sway_is_small_and_smooth() -> None:
    p = VirtualParticipant.from_seed(2)
    t = np.arange(0.0, 60.0, 0.01)
    sway = np.degrees(p.sway(t))
    assert np.abs(sway).max() <= p.sway_deg + 1e-9
    assert np.abs(np.diff(sway, axis=0)).max() < 0.01


def test_validation_refuses_implausible_values() -> None:
    p = VirtualParticipant.from_seed(0)
    with pytest.raises(ValueError):
        replace(p, sex="other")
    with pytest.raises(ValueError):
        replace(p, mass_kg=20.0)
    with pytest.raises(ValueError, match="non-negative"):
        VirtualParticipant.from_seed(-1)
    assert math.isfinite(p.stand_flexion.sum())
