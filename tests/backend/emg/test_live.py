"""Live EMG over LSL, end to end on this machine: the simulated 16-channel 2 kHz amplifier
publishes, the server subscribes a session through the API, and the recording that lands
in the EMG store holds the amplifier's own samples, mapped to the montage, on the server's
LSL clock. A stream of the wrong type or units is refused; a stream that stops ends its
recording with a flag, and one that comes back starts a new, flagged recording."""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Iterator
from typing import Any

import numpy as np
import pylsl
import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.emg import store
from controller.sim.emg_amplifier import N_CHANNELS, EmgTap, channel_labels
from controller.sim.exoskeleton import SimulatedExoskeleton
from tests.polling import wait_for

#: A known clock offset added to liblsl's own correction (0 on one machine), so the test
#: sees that the correction is applied.
SHIFT_S = 250.0
#: Montage channels in an order of their own, labels written differently from the stream's.
ORDER = [5, 0, 11, 3, 8, 1, 10, 2, 7, 4, 9, 6]


class Amplifier:
    """The simulated amplifier ticking at the wearer's 100 Hz in a thread of its own."""

    def __init__(self, source: str, seed: int = 3) -> None:
        self.tap = EmgTap(SimulatedExoskeleton(seed=seed, script="squat-sequence"),
                          name=f"SimEMG-{source}", source_id=source, keep=True)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> Amplifier:
        self.tap.start()
        self._thread.start()
        return self

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            self.tap.tick(None)
            next_t += self.tap.dt
            self._stop.wait(max(0.0, next_t - time.monotonic()))

    def close(self) -> None:
        """Stop ticking and drop the outlet: consumers see the stream end."""
        self._stop.set()
        self._thread.join(5.0)
        self.tap.close()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def samples(self) -> np.ndarray:
        """Everything generated so far, as pushed (float32)."""
        return np.concatenate([b.samples for b in self.tap.blocks]).astype(np.float32)


def _montage() -> dict[str, Any]:
    labels = channel_labels()
    chans = []
    for i in ORDER:
        muscle, _, side = labels[i].rpartition("_")
        chans.append({"label": labels[i].upper().replace("_", " "), "muscle": muscle,
                      "side": side, "placement": "SENIAM", "electrode_type": "Ag/AgCl",
                      "inter_electrode_distance_mm": 20, "reference": "iliac crest"})
    return {"placement_scheme": "SENIAM", "channels": chans}


def _session(client: TestClient, name: str = "Live EMG") -> int:
    study = client.post("/api/studies", json={"name": name}).json()["id"]
    assert client.put(f"/api/studies/{study}/emg-montage", json=_montage()).status_code == 200
    pid = client.post(f"/api/studies/{study}/participants", json={"code": "P1"}).json()["id"]
    return int(client.post(f"/api/participants/{pid}/sessions",
                           json={"kind": "evaluation", "precompression_pct": 25}).json()["id"])


@pytest.fixture
def shifted_clock(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    real = pylsl.StreamInlet.time_correction

    def correction(self: Any, timeout: float = pylsl.FOREVER) -> float:
        return float(real(self, timeout)) + SHIFT_S

    monkeypatch.setattr(pylsl.StreamInlet, "time_correction", correction)
    yield


def _outlet(source: str, kind: str, unit: str) -> pylsl.StreamOutlet:
    info = pylsl.StreamInfo(f"Other-{source}", kind, N_CHANNELS, 2000.0, pylsl.cf_float32,
                            source)
    chans = info.desc().append_child("channels")
    for label in channel_labels():
        ch = chans.append_child("channel")
        ch.append_child_value("label", label)
        ch.append_child_value("unit", unit)
    return pylsl.StreamOutlet(info)


def test_bad_streams_are_refused_with_the_reason(client: TestClient) -> None:
    sess = _session(client)
    url = f"/api/sessions/{sess}/emg-streams"
    spare = [f"spare_{i}" for i in range(1, 5)]
    tag = uuid.uuid4().hex[:8]
    eeg = _outlet(f"test-eeg-{tag}", "EEG", "V")
    newton = _outlet(f"test-force-{tag}", "EMG", "N")
    micro = _outlet(f"test-uv-{tag}", "EMG", "uV")
    text_info = pylsl.StreamInfo(f"Other-text-{tag}", "EMG", N_CHANNELS, 2000.0,
                                 pylsl.cf_string, f"test-text-{tag}")
    text = pylsl.StreamOutlet(text_info)
    try:
        r = client.post(url, json={"name": "x", "source_id": f"test-text-{tag}",
                                   "ignore_labels": spare})
        assert r.status_code == 422 and "hold text" in str(r.json()), r.text
        r = client.post(url, json={"name": "x", "source_id": f"test-eeg-{tag}",
                                   "ignore_labels": spare})
        assert r.status_code == 422 and "not 'EMG'" in str(r.json()), r.text
        r = client.post(url, json={"name": "x", "source_id": f"test-force-{tag}",
                                   "ignore_labels": spare})
        assert r.status_code == 422 and "is not a voltage" in str(r.json()), r.text
        # Spare inputs not named: each listed, with what the montage expects.
        r = client.post(url, json={"name": "x", "source_id": f"test-uv-{tag}"})
        assert r.status_code == 422, r.text
        detail = r.json()["detail"][0]
        assert detail["unmatched_labels"] == spare
        assert len(detail["expected_labels"]) == 12 and detail["missing_labels"] == []
        r = client.post(url, json={"name": "x", "source_id": f"test-none-{tag}"})
        assert r.status_code == 409, r.text
        assert client.get(url).json() == []  # nothing subscribed
        assert client.get(f"/api/sessions/{sess}/emg-recordings").json() == []
    finally:
        del eeg, newton, micro, text


def test_live_emg_is_stored_mapped_and_clock_corrected(
        client: TestClient, settings: Settings, shifted_clock: None,
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(store, "CHUNK_ROWS", 1000)  # 0.5 s per file chunk
    sess = _session(client)
    emg = client.app.state.emg  # type: ignore[attr-defined]
    source = f"test-simemg-{uuid.uuid4().hex[:8]}"
    body = {"name": f"SimEMG-{source}", "source_id": source,
            "ignore_labels": [f"SPARE {i}" for i in range(1, 5)]}
    url = f"/api/sessions/{sess}/emg-streams"
    recs_url = f"/api/sessions/{sess}/emg-recordings"
    with Amplifier(source) as amp:
        r = client.post(url, json=body)
        assert r.status_code == 201, r.text
        sub = r.json()["id"]
        inlet = emg.inlets[sub]
        t_begin = pylsl.local_clock()
        wait_for(lambda: inlet.samples >= 3000, 15, "1.5 s of live EMG in the store")
        # The stream stops mid-recording: the recording ends, flagged, and is kept.
        amp.close()
        t_end = pylsl.local_clock()
        first = wait_for(lambda: [x for x in client.get(recs_url).json()
                                  if x["status"] == "complete"], 10, "the lost stream's "
                         "recording finished")[0]
        generated = amp.samples()
    assert first["source"] == "lsl" and first["fs"] == 2000.0
    assert "stream_lost" in first["quality"]["flags"]
    assert first["labels"] == [_montage()["channels"][k]["label"] for k in range(12)]
    path = store.recording_path(settings, first["id"])
    chunks = list(store.iter_chunks(path))
    assert len(chunks) >= 3  # written in chunks, never whole
    t = np.concatenate([c[0] for c in chunks])
    x = np.concatenate([c[1] for c in chunks])
    n = first["n_samples"]
    assert x.shape == (n, 12) and t.shape == (n,) and n >= 3000
    assert np.isfinite(x).all() and np.isfinite(t).all()
    # The amplifier's own samples, column j being the montage's j-th muscle.
    start = int(np.flatnonzero(generated[:, ORDER[0]] == x[0, 0])[0])
    np.testing.assert_array_equal(x, generated[start:start + n][:, ORDER])
    # Clock: every stamp on this server's clock, corrected by the inlet's estimate.
    np.testing.assert_allclose(np.diff(t), 1 / 2000.0, atol=2e-5)
    assert t_begin - 1.0 < t[0] - SHIFT_S and t[-1] - SHIFT_S < t_end + 1.0
    assert first["t_start"] == pytest.approx(t[0]) and first["t_end"] == pytest.approx(t[-1])
    assert first["quality"]["dropped_samples"] == 0
    assert "rate_mismatch" not in first["quality"]["flags"]

    # The stream comes back: a new recording, flagged as a restart.
    with Amplifier(source, seed=4):
        wait_for(lambda: len(client.get(recs_url).json()) == 2 and inlet.samples > n + 200,
                 15, "a second recording after the stream returned")
        r = client.delete(f"{url}/{sub}")
        assert r.status_code == 200 and r.json()["active"] is False
    second = client.get(recs_url).json()[1]
    assert second["status"] == "complete" and "stream_restarted" in second["quality"]["flags"]
    assert "stream_lost" not in second["quality"]["flags"]
    assert store.read_header(store.recording_path(settings, second["id"])).n_channels == 12
    # The first recording is untouched by what followed.
    assert client.get(recs_url).json()[0] == first


def test_a_sped_up_simulation_loses_no_sample_on_the_way_to_the_store(
        client: TestClient, settings: Settings) -> None:
    """The in-process simulated device of the virtual study, 50 times faster than real
    time: every sample its amplifier pushed is in the recording, in order (counted, not
    timed)."""
    import os

    from controller.sim.simulated_device import SimulatedDevice

    sess = _session(client)
    emg = client.app.state.emg  # type: ignore[attr-defined]
    dev = SimulatedDevice(seed=5, script="lift-evaluation", speed=50.0, emg_lsl=True)
    assert dev.emg is not None
    dev.emg.keep = True
    stop = threading.Event()

    def run() -> None:
        while not stop.is_set():
            dev.read(0.05)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    url = f"/api/sessions/{sess}/emg-streams"
    try:
        r = client.post(url, json={"name": "ExoStudy-SimEMG",
                                   "source_id": f"exostudy-simemg-{os.getpid()}",
                                   "ignore_labels": [f"spare_{i}" for i in range(1, 5)]})
        assert r.status_code == 201, r.text
        inlet = emg.inlets[r.json()["id"]]
        wait_for(lambda: dev.emg is not None and dev.emg.stats.samples_pushed >= 60_000,
                 120, "30 s of sped-up EMG pushed")
    finally:
        stop.set()
        thread.join(5.0)
    pushed = dev.emg.stats.samples_pushed
    wait_for(lambda: inlet.samples >= pushed, 120, "the inlet to pull every pushed sample")
    assert client.delete(f"{url}/{r.json()['id']}").status_code == 200
    dev.close()
    (rec,) = client.get(f"/api/sessions/{sess}/emg-recordings").json()
    assert inlet.samples == pushed and rec["n_samples"] == pushed
    _t, x = store.read_window(store.recording_path(settings, rec["id"]))
    generated = np.concatenate([b.samples for b in dev.emg.blocks]).astype(np.float32)
    np.testing.assert_array_equal(x, generated[:, ORDER])
    assert generated.shape[0] == pushed


def test_one_subscription_per_stream_whatever_the_race_or_the_key(
        client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    """The attack: concurrent identical subscriptions all passed the duplicate check
    before any was stored; name vs name + source id was not seen as the same stream; a
    conflict named another study's session."""
    from concurrent.futures import ThreadPoolExecutor

    from backend.emg import live

    sess = _session(client)
    other_sess = _session(client, "Live EMG elsewhere")  # another study
    source = f"test-dup-{uuid.uuid4().hex[:8]}"
    name = f"SimEMG-{source}"
    spare = [f"SPARE {i}" for i in range(1, 5)]
    gate = threading.Barrier(3)
    real = live.resolve_described

    def resolve_together(n: str, sid: str) -> Any:
        info = real(n, sid)
        try:  # every request has passed any early check before one inserts
            gate.wait(10.0)
        except threading.BrokenBarrierError:
            pass
        return info

    url = f"/api/sessions/{sess}/emg-streams"
    with Amplifier(source):
        monkeypatch.setattr(live, "resolve_described", resolve_together)
        body = {"name": name, "source_id": source, "ignore_labels": spare}
        with ThreadPoolExecutor(3) as pool:
            codes = sorted(r.status_code for r in pool.map(
                lambda _: client.post(url, json=body), range(3)))
        monkeypatch.setattr(live, "resolve_described", real)
        assert codes == [201, 409, 409]
        subs = client.get(url).json()
        assert len(subs) == 1 and subs[0]["source_id"] == source
        # By name only: the same stream.
        r = client.post(url, json={"name": name, "ignore_labels": spare})
        assert r.status_code == 409 and "this study" in r.text, r.text
        # From another study: refused without naming this study's session.
        r = client.post(f"/api/sessions/{other_sess}/emg-streams",
                        json={"name": name, "ignore_labels": spare})
        assert r.status_code == 409 and "another study" in r.text, r.text
        assert f"session {sess}" not in r.text
        client.delete(f"{url}/{subs[0]['id']}")


def _pulled_as_lists(inlet: pylsl.StreamInlet) -> tuple[list[Any], list[float]]:
    """How the inlet pulled before it pulled into an array: one sample with a wait,
    then what else had arrived, as Python lists."""
    first, ts0 = inlet.pull_sample(timeout=0.2)
    if ts0 is None:
        return [], []
    chunk, ts = inlet.pull_chunk(timeout=0.0, max_samples=2047)
    return [first, *chunk], [ts0, *ts]


@pytest.mark.parametrize("fmt", [pylsl.cf_float32, pylsl.cf_double64, pylsl.cf_int16,
                                 pylsl.cf_int32])
def test_pulling_into_an_array_gives_the_samples_the_lists_gave(fmt: int) -> None:
    """Two inlets on one outlet: the array pull and the list pull it replaced yield the
    same volts (montage order, scaled) and stamps, whatever the stream's number type."""
    from backend.emg import live

    source = f"test-pull-{uuid.uuid4().hex[:8]}"
    info = pylsl.StreamInfo(f"Pull-{source}", "EMG", 4, 2000.0, fmt, source)
    outlet = pylsl.StreamOutlet(info, chunk_size=50)
    (found,) = pylsl.resolve_bypred(f"source_id='{source}'", 1, 10.0)
    inlets = [pylsl.StreamInlet(found, max_buflen=360, recover=False) for _ in range(2)]
    for inlet in inlets:
        inlet.open_stream(timeout=10.0)
    cols, volts = np.array([2, 0, 3]), np.array([1e-6, 1e-3, 1.0])
    rng = np.random.default_rng(fmt)
    data = rng.normal(0, 3000, (5000, 4))
    if fmt == pylsl.cf_float32:
        data[rng.integers(5000, size=5), rng.integers(4, size=5)] = [np.nan, np.inf, -np.inf,
                                                                     1e-40, -0.0]
    elif fmt != pylsl.cf_double64:
        data = np.round(data)
    for k in range(0, 5000, 250):
        outlet.push_chunk(data[k:k + 250].tolist(), (10.0 + np.arange(k, k + 250) / 2000.0)
                          .tolist())
    buf = live.pull_buffer(found)
    new_x, new_t, old_x, old_t = [], [], [], []

    def pulled() -> bool:
        ts = live.pull(inlets[0], buf)
        if ts:
            new_x.append(buf[:len(ts), cols] * volts)
            new_t.extend(ts)
        chunk, ts2 = _pulled_as_lists(inlets[1])
        if ts2:
            old_x.append(np.asarray(chunk, dtype=np.float64)[:, cols] * volts)
            old_t.extend(ts2)
        return len(new_t) >= 5000 and len(old_t) >= 5000

    wait_for(pulled, 30, "every sample through both inlets", poll=0.0)
    assert len(new_t) == len(old_t) == 5000
    np.testing.assert_array_equal(new_t, old_t)
    np.testing.assert_array_equal(np.concatenate(new_x), np.concatenate(old_x))
    assert np.concatenate(new_x).dtype == np.float64
    for inlet in inlets:
        inlet.close_stream()


def test_a_pull_buffer_only_for_numbers() -> None:
    from types import SimpleNamespace

    from backend.emg import live

    def info(fmt: int) -> Any:
        return SimpleNamespace(channel_format=lambda: fmt, channel_count=lambda: 3)

    assert live.pull_buffer(info(pylsl.cf_int16)).dtype == np.int16
    assert live.pull_buffer(info(pylsl.cf_float32)).shape == (2048, 3)
    for fmt in (pylsl.cf_string, 0):
        with pytest.raises(ValueError, match="not a number type"):
            live.pull_buffer(info(fmt))
