"""The same simulated EMG, delivered three ways, gives the same per-lift outcomes.

The simulated amplifier (`EmgTap`, 16 channels at 2 kHz) generates 11 s of a virtual
wearer's squats, two complete lifts by the simulation's truth. Those samples reach the
EMG store (1) live over LSL, pushed as the amplifier pushes them (20-sample chunks) to
a session's subscription through the API, (2) as the EMG stream of a LabRecorder XDF
file beside ExoStudy's tick stream, and (3) as a BDF file (edfio). Each recording is
processed with the same chain and each lift's peak, mean and integrated envelope
(`controller.emg.outcomes`) are compared.

Tolerances, derived rather than chosen:
- LSL and XDF carry float32 samples unchanged: the outcomes are identical.
- BDF stores 24-bit integers over its physical range, a step q = span / (2^24 - 1);
  the stored sample is then float32, adding at most 2^-24 of its magnitude. So each
  sample differs by at most e = q / 2 + 2^-24 max|x|. DC removal subtracts the mean
  error (at most e again), rectification does not increase a difference, and each
  linear filter multiplies the worst case by the l1 norm of its (zero-phase) impulse
  response. The envelope, hence peak and mean, differs by at most
  2 e ||h_bandpass||_1 ||h_envelope||_1, and the integral by that times the lift's
  duration. (The chain runs in float64 here so its own rounding stays far below this.)
- The independent implementation (pyemgpipeline, as in tests/controller/emg/
  test_oracle.py) agrees within 1e-6 of the mean envelope.
"""

from __future__ import annotations

import time
import uuid
from pathlib import Path
from typing import Any

import edfio
import numpy as np
import pylsl
from fastapi.testclient import TestClient
from scipy import signal

from backend.core.config import Settings
from backend.emg import store
from controller.emg.outcomes import lift_outcome
from controller.emg.processing import EmgProcessing, design, process
from controller.sim.emg_amplifier import N_CHANNELS, SAMPLES_PER_TICK, EmgTap, channel_labels
from controller.sim.exoskeleton import SimulatedExoskeleton
from tests.backend.lab.test_xdf_import import (
    FILE_SHIFT,
    LSL_MINUS_UNIX,
    _session_with_two_trials,
    _xdf,
)
from tests.backend.lab.xdf_writer import XdfStream, write_xdf
from tests.controller.emg.test_oracle import TOLERANCE as ORACLE_TOLERANCE
from tests.controller.emg.test_oracle import _oracle
from tests.polling import wait_for

FS = 2000.0
TICKS = 1100  # 11 s: whole BDF data records of 1 s
SETTINGS = EmgProcessing(precision="float64")
#: The BDF's physical range (uV): the simulated channels stay well inside +-10 mV.
RANGE_UV = 10_000.0
#: Short labels (EDF/BDF labels have 16 characters), one per amplifier channel.
SHORT = {"erector_spinae_lumbar": "ESL", "erector_spinae_thoracic": "EST",
         "gluteus_maximus": "GM", "biceps_femoris": "BF", "rectus_abdominis": "RA",
         "rectus_femoris": "RF"}
CHANNELS = [label.rpartition("_")[::2] for label in channel_labels()[:12]]
LABELS = [f"{SHORT[m]}-{s[0].upper()}" for m, s in CHANNELS] + [
    f"spare {i}" for i in range(1, N_CHANNELS - 11)]
SPARE = LABELS[12:]


def _simulate() -> tuple[np.ndarray, list[tuple[int, int]]]:
    """(samples (n, 16) float32 volts, lift windows as sample indices) of the wearer."""
    tap = EmgTap(SimulatedExoskeleton(seed=3, script="squat-sequence"), publish=False,
                 keep=True)
    lift = []
    for _ in range(TICKS):
        s = tap.tick(None)
        lift.append(s.truth.lift_index if s.truth is not None else -1)
    x = np.concatenate([b.samples for b in tap.blocks]).astype(np.float32)
    idx = np.asarray(lift)
    windows = []
    for k in sorted(set(idx[idx >= 0])):
        ticks = np.flatnonzero(idx == k)
        if ticks[-1] < TICKS - 1:  # complete lifts only
            windows.append((int(ticks[0]) * SAMPLES_PER_TICK,
                            (int(ticks[-1]) + 1) * SAMPLES_PER_TICK))
    return x, windows


def _montage() -> dict[str, Any]:
    chans = [{"label": label, "muscle": m, "side": side}
             for label, (m, side) in zip(LABELS, CHANNELS, strict=False)]
    return {"placement_scheme": "SENIAM", "channels": chans}


def _live(client: TestClient, settings: Settings, session: int, x: np.ndarray
          ) -> np.ndarray:
    """Push `x` over LSL as the amplifier does, recorded by a subscription."""
    source = f"three-paths-{uuid.uuid4().hex[:8]}"
    info = pylsl.StreamInfo("ThreePathsEMG", "EMG", N_CHANNELS, FS, pylsl.cf_float32, source)
    chans = info.desc().append_child("channels")
    for label in LABELS:
        ch = chans.append_child("channel")
        ch.append_child_value("label", label)
        ch.append_child_value("unit", "V")
    outlet = pylsl.StreamOutlet(info, chunk_size=SAMPLES_PER_TICK, max_buffered=60)
    r = client.post(f"/api/sessions/{session}/emg-streams", json={
        "name": "ThreePathsEMG", "source_id": source, "ignore_labels": SPARE})
    assert r.status_code == 201, r.text
    sub = r.json()["id"]
    inlet = client.app.state.emg.inlets[sub]  # type: ignore[attr-defined]
    wait_for(lambda: inlet.connected, 15, "the subscription's inlet connected")
    # Four times real time: the inlet keeps up (liblsl buffers), the test stays short.
    t0 = pylsl.local_clock()
    for k in range(0, x.shape[0], SAMPLES_PER_TICK):
        outlet.push_chunk(x[k:k + SAMPLES_PER_TICK], t0 + (k + SAMPLES_PER_TICK - 1) / FS)
        if k % 400 == 0:
            time.sleep(0.05)
    wait_for(lambda: inlet.samples >= x.shape[0], 30, "every pushed sample recorded")
    assert client.delete(f"/api/sessions/{session}/emg-streams/{sub}").status_code == 200
    del outlet
    rec = client.get(f"/api/sessions/{session}/emg-recordings").json()[-1]
    assert rec["source"] == "lsl" and rec["n_samples"] == x.shape[0]
    return _samples(settings, rec)


def _samples(settings: Settings, rec: dict[str, Any]) -> np.ndarray:
    t, got = store.read_window(store.recording_path(settings, rec["id"]))
    # In order, no gaps: a lost sample makes a step of 1 ms, a reordered one a negative
    # step. The server adds liblsl's running estimate of the sender's clock offset,
    # re-read at every pull; on a loaded machine a re-estimate moved it by 27 us between
    # two pulls (a fresh-clone run, 2026-11-27), so steps may be off by a fifth of a period.
    np.testing.assert_allclose(np.diff(t), 1 / FS, atol=1e-4)
    return got


def _xdf_file(made: dict[str, Any], x: np.ndarray) -> bytes:
    start = made["ticks"][0][0]["t_host"] + LSL_MINUS_UNIX + FILE_SHIFT
    stamps = [start + i / FS for i in range(x.shape[0])]
    emg = XdfStream("Amplifier", "EMG", LABELS, FS, "float32", stamps, x.tolist(),
                    clock_offsets=[(stamps[0], 0.0), (stamps[-1], 0.0)],
                    units=["V"] * N_CHANNELS, chunks=[SAMPLES_PER_TICK] * (
                        x.shape[0] // SAMPLES_PER_TICK))
    _, streams = _xdf(made["ticks"][0])
    return write_xdf([*streams, emg])


def _bdf_file(x: np.ndarray, tmp: Path) -> bytes:
    signals = [edfio.BdfSignal(x[:, i].astype(np.float64) * 1e6, FS, label=label,
                               physical_dimension="uV",
                               physical_range=(-RANGE_UV, RANGE_UV),
                               digital_range=(-8388608, 8388607))
               for i, label in enumerate(LABELS)]
    path = tmp / "amp.bdf"
    edfio.Bdf(signals).write(path)
    return path.read_bytes()


def _outcomes(env: np.ndarray, lifts: list[tuple[int, int]]) -> np.ndarray:
    """(lift, measure [peak, mean, iemg], channel)."""
    out = []
    for w in lifts:
        o = lift_outcome(env, FS, w).lift
        out.append([o.peak, o.mean, o.iemg])
    return np.asarray(out)


def _l1(sos: np.ndarray) -> float:
    """The l1 norm of a zero-phase (forward-backward) filter's impulse response."""
    n = 40_000
    impulse = np.zeros(n)
    impulse[n // 2] = 1.0
    return float(np.abs(signal.sosfiltfilt(sos, impulse)).sum())


def test_live_xdf_and_bdf_give_the_same_lift_outcomes(
        client: TestClient, settings: Settings, db_url: str, tmp_path: Path) -> None:
    x, lifts = _simulate()
    assert len(lifts) == 2 and x.shape == (TICKS * SAMPLES_PER_TICK, N_CHANNELS)
    assert np.abs(x).max() * 1e6 < RANGE_UV
    made = _session_with_two_trials(db_url)
    session = made["session"]
    assert client.put(f"/api/studies/{made['study']}/emg-montage",
                      json=_montage()).status_code == 200

    live = _live(client, settings, session, x)
    r = client.post(f"/api/sessions/{session}/emg/xdf", data={
        "ignore_labels": ",".join(SPARE), "stream": "Amplifier"},
        files={"file": ("lab.xdf", _xdf_file(made, x), "application/octet-stream")})
    assert r.status_code == 201, r.text
    xdf = _samples(settings, r.json())
    r = client.post(f"/api/sessions/{session}/emg/edf", data={
        "ignore_labels": ",".join(SPARE), "trial": str(made["trials"][0]),
        "offset_s": "0.5"}, files={"file": ("amp.bdf", _bdf_file(x, tmp_path))})
    assert r.status_code == 201, r.text
    assert r.json()["source"] == "bdf"
    bdf = _samples(settings, r.json())

    # The stored samples: LSL and XDF exactly the amplifier's, BDF within its step.
    expected = x[:, :12].astype(np.float64)
    np.testing.assert_array_equal(live, expected)
    np.testing.assert_array_equal(xdf, expected)
    q = 2 * RANGE_UV * 1e-6 / (2**24 - 1)
    e = q / 2 + 2.0**-24 * np.abs(expected).max()
    assert np.abs(bdf - expected).max() <= e

    outcomes = {name: _outcomes(process(v, FS, SETTINGS), lifts)
                for name, v in (("lsl", live), ("xdf", xdf), ("bdf", bdf))}
    np.testing.assert_array_equal(outcomes["lsl"], outcomes["xdf"])
    d = design(SETTINGS, FS)
    bound = 2 * e * _l1(d.bandpass) * _l1(d.envelope)
    durations = np.array([(b - a) / FS for a, b in lifts])[:, None]
    diff = np.abs(outcomes["bdf"] - outcomes["lsl"])
    assert (diff[:, :2] <= bound).all(), (diff[:, :2].max(), bound)
    assert (diff[:, 2] <= bound * durations).all()
    # Meaningful: the bound is far below the outcomes themselves.
    assert bound < 1e-3 * outcomes["lsl"][:, 1].min()

    # The independent implementation, on the same stored samples.
    theirs = _outcomes(_oracle(live, FS, SETTINGS), lifts)
    scale = process(live, FS, SETTINGS).mean()
    assert np.abs(theirs[:, :2] - outcomes["lsl"][:, :2]).max() < ORACLE_TOLERANCE * scale
    assert (np.abs(theirs[:, 2] - outcomes["lsl"][:, 2])
            < ORACLE_TOLERANCE * scale * durations).all()

