"""ExoStudy on LSL, end to end with the real worker: an inlet in the test resolves the
server's tick and marker streams on this machine and checks them against the stored
ticks; a test outlet's markers are stored with the running trial; a console marker
reaches the LSL stream, the trial and the BIDS export, which passes the validator."""

from __future__ import annotations

import io
import json
import statistics
import time
import uuid
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pylsl
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.evidence_tables import Trial
from backend.db.models import Run, ticks_table
from backend.lab.lsl_outlets import TICK_CHANNEL_NAMES
from backend.main import create_app
from backend.study.demo import DEMO_PASSWORD, DEMO_USER
from tests.backend.lab.bids_validator import validate
from tests.login import log_in
from tests.polling import wait_for

pytestmark = pytest.mark.slow


def _independent_offset() -> float:
    """LSL clock minus Unix time, measured here (median of tight pairs)."""
    vals = []
    for _ in range(50):
        a = time.time()
        lsl = pylsl.local_clock()
        b = time.time()
        vals.append(lsl - (a + b) / 2)
    return statistics.median(vals)


def _drain(inlet: pylsl.StreamInlet, into: list[tuple[float, list[Any]]]) -> None:
    while True:
        sample, ts = inlet.pull_sample(timeout=0.0)
        if sample is None:
            return
        into.append((ts, sample))


def test_lsl_streams_markers_and_bids_of_the_demo_study(
        settings: Settings, tmp_path: Path) -> None:
    name = f"ExoStudyTest-{uuid.uuid4().hex[:8]}"
    settings = settings.model_copy(update={"start_worker": True, "demo": True,
                                           "lsl_name": name, "device_speed": 1.0})
    ticks_in: list[tuple[float, list[Any]]] = []
    markers_in: list[tuple[float, list[Any]]] = []
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(
        "ForcePlates", "Markers", 1, pylsl.IRREGULAR_RATE, pylsl.cf_string,
        f"test-forceplates-{name}"))
    with TestClient(create_app(settings)) as client:
        log_in(client, {"username": DEMO_USER, "password": DEMO_PASSWORD})
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 20, 90, "ticks")

        # The server's streams are visible on this machine, with their description.
        found = pylsl.resolve_byprop("name", name, minimum=1, timeout=10.0)
        assert len(found) == 1
        tick_inlet = pylsl.StreamInlet(found[0], max_buflen=60)
        info = tick_inlet.info(timeout=5.0)
        assert info.channel_count() == len(TICK_CHANNEL_NAMES) == 15
        assert info.nominal_srate() == 100.0
        assert info.channel_format() == pylsl.cf_double64
        ch = info.desc().child("channels").child("channel")
        labels, units = [], []
        while not ch.empty():
            labels.append(ch.child_value("label"))
            units.append(ch.child_value("unit"))
            ch = ch.next_sibling()
        assert labels == list(TICK_CHANNEL_NAMES)
        assert units[labels.index("q_left")] == "rad"
        marker_info = pylsl.resolve_byprop("name", f"{name}-Markers", minimum=1, timeout=10)
        assert marker_info and marker_info[0].type() == "Markers"
        marker_inlet = pylsl.StreamInlet(marker_info[0], max_buflen=60)
        tick_inlet.open_stream(timeout=5.0)
        marker_inlet.open_stream(timeout=5.0)

        # The demo study's evaluation session, and a subscription to the test outlet.
        study = next(s for s in client.get("/api/studies").json()
                     if s["name"].startswith("Demo"))
        engine = make_engine(settings.database_url)
        with engine.connect() as conn:
            pec = conn.execute(select(Trial).where(Trial.controller == "pec")
                               .order_by(Trial.planned_order)).first()
        assert pec is not None
        sid = pec.session_id
        visible = client.get(f"/api/sessions/{sid}/lsl-streams").json()
        assert any(s["source_id"] == f"test-forceplates-{name}" and not s["own"]
                   for s in visible)
        assert any(s["name"] == name and s["own"] for s in visible)
        sub = client.post(f"/api/sessions/{sid}/marker-streams", json={
            "name": "ForcePlates", "source_id": f"test-forceplates-{name}"})
        assert sub.status_code == 201, sub.text
        wait_for(lambda: client.get(f"/api/sessions/{sid}/marker-streams").json()[0]["connected"],
              20, "the inlet to connect")

        # A PEC trial runs for a few seconds with a console marker and a foreign one.
        started = client.post(f"/api/trials/{pec.id}/start", json={})
        assert started.status_code == 200, started.text
        wait_for(lambda: client.get("/api/health").json()["worker"]["controller"] == "pec", 30,
              "the trial's controller")
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] >= 100, 30,
                 "1 s of the trial's ticks before the markers")
        offset = _independent_offset()
        outlet.push_sample(["heel strike"], pylsl.local_clock())
        r = client.post(f"/api/sessions/{sid}/markers",
                        json={"label": "box dropped", "note": "left hand"})
        assert r.status_code == 201, r.text
        console = r.json()
        assert console["trial_id"] == pec.id and console["source"] == "console"
        wait_for(lambda: any(m["source"] == "lsl" for m in
                          client.get(f"/api/trials/{pec.id}/markers").json()),
              10, "the test outlet's marker")

        def drained(enough: Callable[[], bool]) -> bool:
            _drain(tick_inlet, ticks_in)
            _drain(marker_inlet, markers_in)
            return enough()

        wait_for(lambda: drained(lambda: len(ticks_in) > 150
                                 and any("box dropped" in s[0] for _, s in markers_in)),
                 30, "150 ticks and the console marker on LSL")
        stopped = client.post(f"/api/trials/{pec.id}/stop", json={"outcome": "completed"})
        assert stopped.status_code == 200, stopped.text
        wait_for(lambda: drained(lambda: any('"trial_stop"' in s[0] for _, s in markers_in)),
                 30, "the trial_stop marker on LSL")
        correction = tick_inlet.time_correction(timeout=5.0)

        # Markers on LSL: trial start with id, blinded label and controller; the console
        # marker; the trial stop; lock edges per side from the held commands.
        events = [json.loads(s[0]) for _, s in markers_in]
        kinds = [e["event"] for e in events]
        start = next(e for e in events if e["event"] == "trial_start")
        assert start["trial_id"] == pec.id and start["controller"] == "pec"
        assert start["blinded_label"] in ("A", "B", "C")
        mark = next(e for e in events if e["event"] == "marker" and e["source"] == "console")
        assert mark["label"] == "box dropped" and mark["trial_id"] == pec.id
        assert kinds.index("trial_start") < kinds.index("marker") < kinds.index("trial_stop")
        assert "heel strike" not in [e.get("label") for e in events]  # not echoed back

        stored = client.get(f"/api/trials/{pec.id}/markers").json()
        foreign = next(m for m in stored if m["source"] == "lsl")
        assert foreign["label"] == "heel strike" and foreign["trial_id"] == pec.id
        assert {m["label"] for m in stored if m["source"] == "system"} == {
            "trial_start", "trial_stop"}

        # BIDS export of the demo study: valid, with the console marker in the events.
        z = client.get(f"/api/studies/{study['id']}/export.bids.zip")
        assert z.status_code == 200
        zipfile.ZipFile(io.BytesIO(z.content)).extractall(tmp_path)
    outlet = None

    # Tick stream against the stored ticks, matched by sequence number.
    with engine.connect() as conn:
        run_ids = [r[0] for r in conn.execute(select(Run.id))]
        rows = conn.execute(select(ticks_table).where(ticks_table.c.run_id.in_(run_ids))
                            ).mappings().all()
    engine.dispose()
    by_seq = {int(r["seq"]): r for r in rows}
    assert len(ticks_in) > 150
    matched = 0
    diffs = []
    for ts, sample in ticks_in:
        r = by_seq.get(int(sample[0]))
        if r is None:
            continue
        matched += 1
        for name_, v in zip(TICK_CHANNEL_NAMES, sample, strict=True):
            want = r[name_]
            if want is None:
                assert np.isnan(v), name_
            else:
                assert v == float(want), name_
        diffs.append(ts + correction - (r["t_host"] + offset))
    assert matched == len(ticks_in)
    # Stamped with the sample's own read time on the LSL clock: within 1 ms.
    assert max(abs(d) for d in diffs) < 1e-3, (correction, min(diffs), max(diffs))
    stamps = np.array([ts for ts, _ in ticks_in])
    assert np.median(np.diff(stamps)) == pytest.approx(0.01, abs=2e-3)

    root = next(tmp_path.glob("study-*-bids"))
    assert validate(root) == []
    events_files = list(root.glob("sub-*/ses-*/motion/*acq-pec*_events.tsv"))
    assert events_files
    text = "".join(f.read_text() for f in events_files)
    assert "box dropped: left hand\tconsole" in text and "heel strike\tlsl" in text
