"""The simulated EMG amplifier: fed by the simulated wearer tick by tick, published on LSL
and received by a real inlet on this machine."""

from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from controller.sim.emg_amplifier import N_CHANNELS, EmgTap, channel_labels
from controller.sim.exoskeleton import SimulatedExoskeleton
from tests.polling import wait_for

# liblsl reads its configuration at its first call: this machine only, loopback peers.
os.environ.setdefault(
    "LSLAPICFG", str(Path(__file__).parents[2] / "backend" / "lab" / "lsl_api.cfg"))


def test_tap_follows_the_wearer_and_spots_movement_onsets() -> None:
    tap = EmgTap(SimulatedExoskeleton(seed=2, script="squat-sequence"), publish=False, keep=True)
    n = 800
    for _ in range(n):
        tap.tick(None)
    x = np.concatenate([b.samples for b in tap.blocks])
    act = np.concatenate([b.activation for b in tap.blocks])
    assert x.shape == (n * 20, N_CHANNELS)
    assert tap.stats.onsets >= 1  # standing, then the first lift
    assert np.all(act[:, 12:] == 0)  # spare inputs hold no muscle
    es = act[:, 0]
    assert es.max() > 5 * es.min()  # the lift shows in the back's activation
    assert len(set(channel_labels())) == N_CHANNELS


def test_emg_reaches_an_lsl_inlet_at_2_khz() -> None:
    pylsl: Any = pytest.importorskip("pylsl")
    source = f"test-simemg-{uuid.uuid4().hex[:8]}"
    tap = EmgTap(SimulatedExoskeleton(seed=1, script="squat-sequence"), source_id=source)
    tap.start()
    try:
        found = pylsl.resolve_byprop("source_id", source, minimum=1, timeout=10.0)
        assert len(found) == 1
        inlet = pylsl.StreamInlet(found[0], max_buflen=10)
        inlet.open_stream(timeout=10.0)
        info = inlet.info(timeout=5.0)
        assert (info.type(), info.channel_count(), info.nominal_srate()) == ("EMG", 16, 2000.0)
        assert info.channel_format() == pylsl.cf_float32
        ch = info.desc().child("channels").child("channel")
        labels, units, types = [], [], []
        for _ in range(N_CHANNELS):
            labels.append(ch.child_value("label"))
            units.append(ch.child_value("unit"))
            types.append(ch.child_value("type"))
            ch = ch.next_sibling()
        assert labels == channel_labels() and set(units) == {"V"} and set(types) == {"EMG"}
        montage = info.desc().child("montage")
        assert montage.child_value("inter_electrode_distance_mm") == "20"

        ticks = 100  # one second of ticks: 2000 samples
        for _ in range(ticks):
            tap.tick(None)
        got: list[np.ndarray] = []
        stamps: list[np.ndarray] = []

        def pulled() -> bool:
            data, ts = inlet.pull_chunk(timeout=0.0)
            if ts:
                got.append(np.asarray(data))
                stamps.append(np.asarray(ts))
            return sum(len(s) for s in stamps) >= ticks * 20

        wait_for(pulled, 20.0, "2000 EMG samples on the inlet")
        x, t = np.concatenate(got), np.concatenate(stamps)
        assert x.shape == (ticks * 20, N_CHANNELS)
        assert np.all(np.isfinite(x))
        np.testing.assert_allclose(np.diff(t), 1 / 2000.0, atol=1e-6)
        assert tap.stats.samples_pushed == ticks * 20
        # Values are the generator's, in volts (float32).
        assert 1e-6 < float(np.std(x[:, 0])) < 5e-3
    finally:
        tap.close()


class _FakeOutlet:
    """Keeps what is pushed; `consumers` says whether an inlet listens."""

    def __init__(self) -> None:
        self.stamps: list[float] = []
        self.rows = 0
        self.consumers = True

    def have_consumers(self) -> bool:
        return self.consumers

    def push_chunk(self, x: Any, stamps: list[float]) -> None:
        assert len(stamps) == len(x)
        self.stamps += stamps
        self.rows += len(x)


def test_spread_stamps_follow_the_reader_clock_and_never_go_back() -> None:
    """A sped-up in-process simulator: each tick's 20 samples end at the instant the
    tick is produced, evenly spaced since the previous tick, never backwards; with no
    consumer nothing is generated."""
    tap = EmgTap(SimulatedExoskeleton(seed=3, script="squat-sequence"), stamping="spread",
                 only_when_consumed=True)
    out = _FakeOutlet()
    clock = iter(np.concatenate([1000.0 + 0.0001 * np.arange(50),  # 100x real time
                                 1000.0049 + np.zeros(5)]))  # a clock that stalls
    tap._outlet, tap._clock = out, lambda: next(clock)
    for _ in range(55):
        tap.tick(None)
    s = np.asarray(out.stamps)
    assert out.rows == 55 * 20 and s.size == out.rows
    assert np.all(np.diff(s) > 0)
    ends = s[19::20]
    assert np.allclose(ends[1:50], 1000.0 + 0.0001 * np.arange(1, 50))
    assert np.allclose(np.diff(s[20:40]), 0.0001 / 20)
    assert s[0] == pytest.approx(1000.0 - 20 / 2000 + 1 / 2000)  # first tick: nominal
    out.consumers = False
    made = tap.generator.samples_generated
    tap.tick(None)
    assert out.rows == 55 * 20 and tap.generator.samples_generated == made


def test_not_worn_wearer_gets_no_torque_and_full_muscle_demand() -> None:
    """The "no exoskeleton" baseline: locks asked for are ignored, the springs give no
    torque, and the muscles carry the whole moment."""
    from controller.device.base import LockCommand

    worn, bare = (SimulatedExoskeleton(seed=4, script="squat-sequence") for _ in range(2))
    bare.worn = False
    tw: list[tuple[float, float]] = []
    tb: list[tuple[float, float]] = []
    aw, ab = EmgTap(worn, publish=False), EmgTap(bare, publish=False)
    for k in range(2500):
        for exo, acc in ((worn, tw), (bare, tb)):
            exo.tick(LockCommand(seq=k, lock_left=True, lock_right=True))
            acc.append(exo.true_torques())
        if k % 10 == 0:  # the extensors (not the flexors, which springs may load)
            ext = [0, 1, 2, 3, 6, 7, 8, 9]
            assert np.all(ab.activation()[ext] >= aw.activation()[ext] - 1e-12)
    assert np.max(tw) > 5.0
    assert np.max(np.abs(tb)) == 0.0


def test_a_late_reader_s_burst_keeps_the_sample_clock() -> None:
    """The attack: the in-server amplifier at real speed was flagged dropped_samples
    and rate_mismatch with nothing lost: a late reader takes waiting ticks at once and
    spread stamps squeezed them after a gap. Stamped at each tick's due instant, the
    samples keep the nominal spacing and the timing check finds nothing."""
    from controller.emg.quality import timing_quality

    tap = EmgTap(SimulatedExoskeleton(seed=3, script="squat-sequence"), stamping="spread")
    out = _FakeOutlet()
    dt = tap.dt
    # Ticks due every 10 ms; the reader is 35 ms late for ticks 10-13 and reads them at
    # once, then catches up.
    reads = [(k * dt, 0.0) if not 10 <= k <= 13 else (14 * dt - 1e-4, 14 * dt - 1e-4 - k * dt)
             for k in range(40)]
    now = iter([r for r, _ in reads])
    tap._outlet, tap._clock = out, lambda: next(now)
    for _, late in reads:
        tap.emit(tap.model.tick(None), late)
    q = timing_quality(np.asarray(out.stamps), 2000.0)
    assert q.flags == () and q.dropped_samples == 0
    assert np.allclose(np.diff(out.stamps), 1 / 2000.0, atol=1e-6)
