"""The simulated wearer's EMG, computed ahead in blocks and per tick in Python floats,
equals the plain per-tick numpy it replaced (`reference_emg.py`) sample for sample: the
same random streams in the same order, the same filter states, the same stamps."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.device.base import GroundTruth, LockCommand, Sample
from controller.sim.emg_amplifier import EmgTap
from controller.sim.exoskeleton import SimulatedExoskeleton
from controller.sim.muscles import MuscleModel
from controller.sim.participant import VirtualParticipant
from controller.sim.surface_emg import (
    AHEAD,
    SENSOR_TABLE,
    EmgBlock,
    EmgSettings,
    Faults,
    SurfaceEmgGenerator,
)
from tests.controller.sim.reference_emg import (
    ReferenceGenerator,
    ReferenceMuscles,
    ReferenceTap,
)

moment = st.one_of(st.floats(-400.0, 500.0, allow_nan=False), st.sampled_from([0.0, -0.0]))


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(moment, moment, moment, moment), min_size=1, max_size=30),
       st.integers(0, 10_000), st.booleans())
def test_one_tick_s_activation_is_the_reference_s(rows: list[tuple[float, ...]], seed: int,
                                                  supported: bool) -> None:
    model = MuscleModel.for_participant(VirtualParticipant.from_seed(seed))
    arr = np.array(rows)
    if supported:  # the exoskeleton giving exactly the moment on some ticks
        arr[::3, 2:] = arr[::3, :2]
    ref = ReferenceMuscles(model).activation(arr[:, :2], arr[:, 2:])
    ticks = np.array([model.tick_activation(r[:2], r[2:]) for r in arr])
    np.testing.assert_array_equal(ticks, ref)
    np.testing.assert_array_equal(model.activation(arr[:, :2], arr[:, 2:]), ref)


def test_a_non_finite_moment_gives_the_reference_s_nan() -> None:
    model = MuscleModel.from_body(70.0, seed=3)
    for human in ((math.nan, 10.0), (math.inf, 0.0), (-math.inf, 5.0)):
        ref = ReferenceMuscles(model).activation(human, (0.0, 0.0))[0]
        np.testing.assert_array_equal(model.tick_activation(human, (0.0, 0.0)), ref)
    assert np.isnan(model.tick_activation((math.nan, 10.0), (0.0, 0.0))).any()


def _same(got: list[EmgBlock], ref: list[EmgBlock]) -> None:
    """Block for block the same times, samples, activation and gains."""
    assert [b.t.size for b in got] == [b.t.size for b in ref]
    for field in ("t", "samples", "activation"):
        np.testing.assert_array_equal(np.concatenate([getattr(b, field) for b in got]),
                                      np.concatenate([getattr(b, field) for b in ref]))
    for a, b in zip(got, ref, strict=True):
        assert np.array_equal(a.gain_v, b.gain_v)


SETTINGS = [
    EmgSettings(),
    EmgSettings(mains_hz=60.0),
    EmgSettings(mains_hz=None),
    EmgSettings(faults=Faults(clip_v=0.3e-3, flat=(1,), drop_every=3, drop_length=7)),
    EmgSettings(faults=Faults(stop_after_s=0.4)),
]


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(range(len(SETTINGS))),
       st.lists(st.tuples(st.integers(1, 45), st.booleans(), st.booleans()),
                min_size=1, max_size=15))
def test_generator_blocks_are_the_reference_s(seed: int, which: int,
                                              blocks: list[tuple[int, bool, bool]]) -> None:
    """Any cut into blocks (ticks or samples), onsets anywhere (overlapping artefacts
    included), across the blocks computed ahead (`AHEAD` samples): the same samples."""
    channels = 3
    new = SurfaceEmgGenerator(channels, seed, SETTINGS[which])
    ref = ReferenceGenerator(channels, seed, SETTINGS[which])
    rng = np.random.default_rng(seed)
    got, want = [], []
    for ticks, onset, at_sample_rate in blocks:
        if onset:
            new.onset()
            ref.onset()
        if at_sample_rate:
            act = rng.uniform(-0.2, 1.2, (ticks * 7, channels))
            got.append(new.push_samples(act))
            want.append(ref.push_samples(act))
        else:
            act = rng.uniform(-0.2, 1.2, (ticks, channels))
            got.append(new.push(act))
            want.append(ref.push(act))
        assert new.samples_generated == ref._n
    _same(got, want)


def test_generator_ticks_across_the_sensor_table_s_end_are_the_reference_s() -> None:
    """Ticks one at a time across the end of the sensor noise table and many refills of
    the noise computed ahead: the same samples as one block each way."""
    new, ref = SurfaceEmgGenerator(16, 11), ReferenceGenerator(16, 11)
    rng = np.random.default_rng(11)
    first = rng.uniform(0.0, 1.0, (SENSOR_TABLE // 20 - 3, 16))
    got, want = [new.push(first)], [ref.push(first)]
    for k in range(AHEAD // 20 + 9):
        if k % 60 == 5:
            new.onset()
            ref.onset()
        row = rng.uniform(0.0, 1.0, 16)
        got.append(new.push(row))
        want.append(ref.push(row))
    assert new.samples_generated > SENSOR_TABLE
    _same(got, want)


class _Wearer:
    """A scripted wearer: seeded moments and torques, activities of scripted lengths."""

    dt = 0.01

    def __init__(self, seed: int, pattern: str, ticks: int) -> None:
        self.seed = seed
        self.participant = VirtualParticipant.from_seed(seed)
        r = np.random.default_rng(seed)
        t = np.arange(ticks) * self.dt
        if pattern == "lifts":  # smooth lifts, supported by springs, a new one every ~1 s
            bump = np.maximum(0.0, np.sin(2 * np.pi * t / 2.0))[:, None]
            self.human = 150.0 * bump * r.uniform(0.6, 1.2, 2)
            self.exo = 0.4 * self.human
            lengths = r.integers(70, 150, ticks)
        elif pattern == "bursts":  # activity changing every few ticks: artefacts overlap
            self.human = r.uniform(-50.0, 300.0, (ticks, 2))
            self.exo = r.uniform(0.0, 60.0, (ticks, 2))
            lengths = r.integers(1, 12, ticks)
        else:  # "flexion": springs giving more than needed, saturation, exact zeros
            self.human = r.uniform(-120.0, 400.0, (ticks, 2))
            self.exo = np.where(r.random((ticks, 2)) < 0.3, self.human,
                                r.uniform(0.0, 200.0, (ticks, 2)))
            lengths = r.integers(20, 60, ticks)
        edges = np.cumsum(lengths)
        self.activity = [f"a{int(np.searchsorted(edges, k, side='right')) % 3}"
                         for k in range(ticks)]
        self.k = -1

    @property
    def finished(self) -> bool:
        """After the scripted ticks."""
        return self.k + 1 >= len(self.activity)

    def tick(self, command: LockCommand | None) -> Sample:
        """The next scripted tick."""
        self.k += 1
        return Sample(seq=self.k, t=self.k * self.dt, counts=(0, 0, 0, 0),
                      truth=GroundTruth(activity=self.activity[self.k]))

    def human_torques(self) -> tuple[float, float]:
        """The scripted moments now."""
        return float(self.human[self.k, 0]), float(self.human[self.k, 1])

    def true_torques(self) -> tuple[float, float]:
        """The scripted torques now."""
        return float(self.exo[self.k, 0]), float(self.exo[self.k, 1])


class _Outlet:
    """Keeps what is pushed, as an LSL outlet would send it."""

    def __init__(self) -> None:
        self.data: list[np.ndarray] = []
        self.stamps: list[float] = []

    def have_consumers(self) -> bool:
        return True

    def push_chunk(self, x: np.ndarray, stamps: list[float]) -> None:
        self.data.append(np.array(x))
        self.stamps += stamps


def _run_both(model: Any, ticks: int) -> None:
    """Every tick through the tap and through the reference: blocks, onsets, pushed
    float32 chunks and their spread stamps (on a clock that runs, stalls and reads late)."""
    tap = EmgTap(model, stamping="spread", keep=True)
    ref = ReferenceTap(tap.muscles, model.seed)
    out = _Outlet()
    clock = iter(1000.0 + np.cumsum(np.random.default_rng(model.seed).choice(
        [0.0, 1e-4, 0.01, 0.05], ticks)))
    now = 0.0

    def read() -> float:
        return now

    tap._outlet, tap._clock = out, read
    want: list[EmgBlock] = []
    stamps: list[float] = []
    for k in range(ticks):
        now = float(next(clock))
        late = 0.003 if k % 17 == 3 else 0.0
        sample = model.tick(None)
        tap.emit(sample, late)
        want.append(ref.emit(sample, model.human_torques(), model.true_torques()))
        stamps += ref.spread_stamps(want[-1], now, late)
    _same(tap.blocks, want)
    np.testing.assert_array_equal(np.concatenate(out.data),
                                  np.concatenate([b.samples for b in want]).astype(np.float32))
    assert out.stamps == stamps
    assert tap.stats.onsets == ref.onsets > 0


@pytest.mark.parametrize(("seed", "pattern"), [(1, "lifts"), (2, "bursts"), (3, "flexion")])
def test_tap_emits_the_reference_samples_and_stamps(seed: int, pattern: str) -> None:
    ticks = 450  # 9,000 samples: two refills of the noise computed ahead
    _run_both(_Wearer(seed, pattern, ticks), ticks)


def test_tap_on_the_simulated_exoskeleton_emits_the_reference_samples() -> None:
    _run_both(SimulatedExoskeleton(seed=5, script="squat-sequence"), 450)
