"""XDF import: a file written here (pyxdf's reader as the oracle of the writer) is
attached to a session, its streams are put on ExoStudy's clock and matched to trials;
bad and hostile files (issues 23 and 28) are refused with a 422 naming the file and
what is wrong, within the limits the settings give; the CLI's BIDS export carries it."""

from __future__ import annotations

import math
import resource
import struct
import tempfile
import tracemalloc
import uuid
from collections.abc import Callable, Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import pyxdf
from fastapi.testclient import TestClient
from sqlalchemy import insert
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.db.models import Participant, Run, Study, StudySession, ticks_table
from backend.lab import xdf_import
from backend.lab.lsl_outlets import TICK_CHANNEL_NAMES
from backend.lab.xdf_reader import XdfError
from backend.schemas.lab import XdfStreamSummary
from controller.tick_record import TickRecord
from tests.backend.lab import xdf_hostile
from tests.backend.lab.xdf_writer import XdfStream, chunk, header_xml, write_xdf

#: ExoStudy's LSL clock minus Unix time in the made-up session (a machine up ~10 min).
LSL_MINUS_UNIX = 600.0 - 1.7e9
#: The LabRecorder computer's clock minus ExoStudy's: another host, 1000.25 s apart.
FILE_SHIFT = 1000.25


def _ticks(run_id: int, seq0: int, t_host0: float, n: int) -> list[dict[str, Any]]:
    rows = []
    for i in range(n):
        r = TickRecord(seq=seq0 + i, t=i / 100, t_host=t_host0 + i / 100,
                       q_left=0.5 * math.sin(i / 40), q_right=0.4 * math.sin(i / 40),
                       lock_left=150 <= i < 220, lock_right=150 <= i < 220)
        d = {k: (None if isinstance(v, float) and v != v else v)
             for k, v in r.as_dict().items()}
        d["run_id"] = run_id
        rows.append(d)
    return rows


def _session_with_two_trials(db_url: str) -> dict[str, Any]:
    """A session whose two trials ran 10 s apart, each with start and stop markers."""
    engine = make_engine(db_url)
    out: dict[str, Any] = {"trials": [], "ticks": []}
    with Session(engine) as db:
        study = Study(name="Lab study")
        db.add(study)
        db.flush()
        p = Participant(study_id=study.id, code="P01", age=31, sex="female", height_m=1.68,
                        mass_kg=61.0, notes="private note")
        db.add(p)
        db.flush()
        sess = StudySession(participant_id=p.id, kind="evaluation", precompression_pct=25.0)
        db.add(sess)
        db.flush()
        for k, (task, start) in enumerate((("squat-sequence", 1.7e9 + 5.0),
                                           ("stoop-sequence", 1.7e9 + 20.0))):
            run = Run(device_kind="sim", controller="pec")
            db.add(run)
            db.flush()
            trial = Trial(session_id=sess.id, controller="pec", task=task, planned_order=k,
                          status="completed", run_id=run.id)
            db.add(trial)
            db.flush()
            rows = _ticks(run.id, 1000 * (k + 1), start, 300)
            db.execute(insert(ticks_table), rows)
            for label, i in (("trial_start", 0), ("trial_stop", 299)):
                db.add(Marker(session_id=sess.id, trial_id=trial.id, run_id=run.id,
                              t=rows[i]["t"], lsl_time=rows[i]["t_host"] + LSL_MINUS_UNIX,
                              label=label, note="", source="system"))
            db.add(Marker(session_id=sess.id, trial_id=trial.id, run_id=run.id, t=1.5,
                          lsl_time=start + 1.5 + LSL_MINUS_UNIX, label="box dropped",
                          note="", source="console"))
            out["trials"].append(trial.id)
            out["ticks"].append(rows)
        db.commit()
        out["study"], out["session"] = study.id, sess.id
    engine.dispose()
    return out


def _xdf(ticks: list[dict[str, Any]]) -> tuple[bytes, list[XdfStream]]:
    """The first trial's ticks as LabRecorder on another host would have them, a motion
    capture stream over the same 3 s, and a marker stream."""
    lsl = [r["t_host"] + LSL_MINUS_UNIX + FILE_SHIFT for r in ticks]
    exo = XdfStream("ExoStudy", "ExoskeletonTicks", list(TICK_CHANNEL_NAMES), 100.0,
                    "double64", lsl,
                    [[float(r[c] or 0.0) for c in TICK_CHANNEL_NAMES] for r in ticks],
                    source_id="exostudy-ticks", clock_offsets=[(lsl[0], 0.0), (lsl[-1], 0.0)])
    n = 600
    mocap = XdfStream("Mocap", "MoCap", ["pelvis_x", "pelvis_y", "pelvis_z"], 200.0,
                      "double64", [lsl[0] + i / 200 for i in range(n)],
                      [[0.01 * i, 1.0, -0.5] for i in range(n)],
                      clock_offsets=[(lsl[0], 0.0), (lsl[-1], 0.0)])
    marks = XdfStream("ForcePlateMarkers", "Markers", ["event"], 0.0, "string",
                      [lsl[50], lsl[120]], [["heel strike"], ["toe off"]],
                      clock_offsets=[(lsl[0], 0.0), (lsl[-1], 0.0)])
    streams = [exo, mocap, marks]
    return write_xdf(streams), streams


def test_the_writer_is_read_back_by_pyxdf(tmp_path: Path) -> None:
    ticks = _ticks(1, 10, 1.7e9, 200)
    data, written = _xdf(ticks)
    path = tmp_path / "check.xdf"
    path.write_bytes(data)
    streams, _ = pyxdf.load_xdf(str(path), dejitter_timestamps=False)
    by_name = {s["info"]["name"][0]: s for s in streams}
    assert set(by_name) == {"ExoStudy", "Mocap", "ForcePlateMarkers"}
    for w in written:
        got = by_name[w.name]
        np.testing.assert_allclose(got["time_stamps"], w.stamps, rtol=0, atol=1e-9)
        if w.fmt == "string":
            assert got["time_series"] == w.rows
        else:
            np.testing.assert_array_equal(np.asarray(got["time_series"]), np.asarray(w.rows))


def test_an_xdf_file_is_aligned_with_the_trials(client: TestClient, db_url: str,
                                                tmp_path: Path) -> None:
    made = _session_with_two_trials(db_url)
    data, _ = _xdf(made["ticks"][0])
    sid = made["session"]
    r = client.post(f"/api/sessions/{sid}/xdf",
                    files={"file": ("lab-recording.xdf", data, "application/octet-stream")})
    assert r.status_code == 201, r.text
    att = r.json()
    assert att["size_bytes"] == len(data) and att["filename"] == "lab-recording.xdf"
    streams = {s["name"]: s for s in att["streams"]}
    first, second = made["trials"]
    exo = streams["ExoStudy"]
    assert exo["exostudy"] and exo["samples"] == 300 and exo["channel_count"] == 15
    # The file's clock is found 1000.25 s ahead of ours, to well under a millisecond.
    assert exo["offset_ms"] == pytest.approx(FILE_SHIFT * 1000.0, abs=1e-3)
    assert exo["trial_ids"] == [first]
    assert streams["Mocap"]["trial_ids"] == [first]
    assert streams["Mocap"]["channels"] == ["pelvis_x", "pelvis_y", "pelvis_z"]
    assert streams["ForcePlateMarkers"]["trial_ids"] == [first] and second not in \
        streams["ForcePlateMarkers"]["trial_ids"]
    # Kept byte for byte.
    assert client.get(f"/api/sessions/{sid}/xdf/{att['id']}/file").content == data
    assert [a["id"] for a in client.get(f"/api/sessions/{sid}/xdf").json()] == [att["id"]]

    # A file that is not XDF, or is cut short, is a 422 naming the file; nothing stored.
    for bad in (b"PK\x03\x04 not xdf", data[: len(data) // 3]):
        r = client.post(f"/api/sessions/{sid}/xdf",
                        files={"file": ("broken.xdf", bad, "application/octet-stream")})
        assert r.status_code == 422, r.text
        assert r.json()["detail"][0]["loc"] == ["body", "file"]
    assert len(client.get(f"/api/sessions/{sid}/xdf").json()) == 1
    assert client.post("/api/sessions/999999/xdf", files={
        "file": ("a.xdf", data, "application/octet-stream")}).status_code == 404


def test_cli_bids_export_carries_trials_markers_and_the_xdf(
        client: TestClient, db_url: str, tmp_path: Path) -> None:
    from backend.cli import main
    from tests.backend.lab.bids_validator import validate

    made = _session_with_two_trials(db_url)
    data, _ = _xdf(made["ticks"][0])
    assert client.post(f"/api/sessions/{made['session']}/xdf", files={
        "file": ("lab.xdf", data, "application/octet-stream")}).status_code == 201
    out = tmp_path / "bids"
    assert main(["export", "--study", str(made["study"]), "--bids", str(out),
                 "--db", db_url]) == 0
    assert validate(out) == []
    motion = sorted(out.glob("sub-P01/ses-*/motion/*_motion.tsv"))
    assert len(motion) == 2
    # One row per stored tick, no header, the channels in _channels.tsv's order.
    rows = [line.split("\t") for line in motion[0].read_text().splitlines()]
    assert len(rows) == 300
    names = [line.split("\t")[0] for line in
             Path(str(motion[0]).replace("_motion.tsv", "_channels.tsv")).read_text()
             .splitlines()[1:]]
    stored = made["ticks"][0]
    for i in (0, 123, 299):
        assert float(rows[i][names.index("q_left")]) == stored[i]["q_left"]
        assert int(rows[i][names.index("lock_left")]) == int(stored[i]["lock_left"])
    events = next(out.glob("sub-P01/ses-*/motion/*task-squatsequence*_events.tsv"))
    ev = [line.split("\t") for line in events.read_text().splitlines()]
    assert ev[0][:3] == ["onset", "duration", "trial_type"]
    assert ["1.5", "0.0", "marker", "n/a", "box dropped", "console"] in [e[:6] for e in ev]
    participants = (out / "participants.tsv").read_text()
    assert "sub-P01" in participants and "private note" not in participants
    assert len(list(out.glob("sourcedata/sub-P01/ses-*/*.xdf"))) == 1
    # A second export into the same folder is refused rather than mixed in.
    assert main(["export", "--study", str(made["study"]), "--bids", str(out),
                 "--db", db_url]) == 2
    with tempfile.TemporaryDirectory() as empty:
        assert main(["export", "--study", "999", "--bids", empty, "--db", db_url]) == 2


# Hostile and damaged files (issues 23 and 28) ---------------------------------------------
def _session(client: TestClient) -> int:
    r = client.post("/api/studies", json={"name": f"X-{uuid.uuid4().hex[:8]}"})
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    pid = client.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"]
    r = client.post(f"/api/participants/{pid}/sessions",
                    json={"kind": "evaluation", "precompression_pct": 25})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _post(client: TestClient, session_id: int, data: bytes) -> Any:
    return client.post(f"/api/sessions/{session_id}/xdf",
                       files={"file": ("crafted.xdf", data, "application/octet-stream")})


def _refused(r: Any, *words: str) -> str:
    """The 422's message, checked to name the file and to contain `words`."""
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    assert detail["loc"] == ["body", "file"]
    for w in words:
        assert w in detail["msg"], detail["msg"]
    return str(detail["msg"])


@pytest.fixture
def client_with(settings: Settings, experimenter: dict[str, str]
                ) -> Iterator[Callable[..., TestClient]]:
    """Logged-in TestClients whose settings differ from the defaults by the given
    fields (closed at the end of the test)."""
    from backend.main import create_app
    from tests.login import log_in

    opened: list[TestClient] = []

    def make(**update: Any) -> TestClient:
        app = create_app(settings.model_copy(update={"device_spawn_simulator": False,
                                                     **update}))
        c = TestClient(app)
        c.__enter__()
        opened.append(c)
        log_in(c, experimenter)
        return c

    yield make
    for c in opened:
        c.__exit__(None, None, None)


def test_a_chunk_that_declares_more_than_it_holds_is_refused(client: TestClient) -> None:
    # Issue 28: the sample of a Samples chunk declaring 1 string sample in its last 3
    # bytes ran on into the next chunk, where hidden chunks declared 50 million samples:
    # 201 after 17.5 s with the parser at 2 GB. Issue 23: a count, or a channel count,
    # far beyond the file's bytes.
    sid = _session(client)
    _refused(_post(client, sid, xdf_hostile.past_its_end()), "Samples, stream 1",
             "runs past the chunk's end")
    _refused(_post(client, sid, xdf_hostile.declaring(30_000_000)), "30000000 samples")
    _refused(_post(client, sid, xdf_hostile.declaring(5_000_000, 100, "double64")),
             "5000000 samples")
    _refused(_post(client, sid, b"XDF:" + chunk(2, struct.pack("<I", 1) + header_xml(
        "x", "EEG", 250_000_000, 100, "float32"))), "channel_count")
    assert client.get(f"/api/sessions/{sid}/xdf").json() == []


def test_a_large_string_stream_stays_out_of_the_server(client: TestClient) -> None:
    # Issue 28: the parsed streams came back into the server; an 18 MB string stream
    # took it from 409 to 1,112 MB. Now a summary comes back and the server grows by
    # little more than the upload's own copies.
    data = xdf_hostile.string_stream(1_400_000)
    sid = _session(client)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    r = _post(client, sid, data)
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    assert r.status_code == 201, r.text
    stream = r.json()["streams"][0]
    assert stream["samples"] == 1_400_000 and stream["first_time"] == 100.0
    assert stream["last_time"] == pytest.approx(100.0 + 1_399_999 / 1e3)
    assert grown_mb < 150, grown_mb


def test_a_flood_of_chunks_is_refused_at_the_chunk_limit(client: TestClient) -> None:
    # Issue 28: 2 million boundary chunks in 8 MB took 11.6 s and were accepted.
    data = write_xdf([xdf_hostile.small_stream()]) + b"\x01\x02\x05\x00" * 2_000_000
    sid = _session(client)
    _refused(_post(client, sid, data), "more than 1000000 chunks", "xdf_max_chunks")


def test_twenty_thousand_random_clock_offsets_are_read_at_once(
        client: TestClient, client_with: Callable[..., TestClient]) -> None:
    # Issue 28: 20,000 ClockOffset chunks of random values (481 kB) took 465 s of a core
    # (a robust fit per clock reset); the fit is now one pass over the offsets per round.
    data = xdf_hostile.clock_offsets(20_000)
    assert len(data) < 500_000
    sid = _session(client)
    r = _post(client, sid, data)
    assert r.status_code == 201, r.text
    stream = r.json()["streams"][0]
    assert stream["samples"] == 50 and math.isfinite(stream["first_time"])
    # The count itself is bounded by a setting.
    tight = client_with(xdf_max_clock_offsets=10_000)
    _refused(_post(tight, _session(tight), data), "more than 10000 clock offsets",
             "xdf_max_clock_offsets")


def test_the_limits_come_from_the_settings(client_with: Callable[..., TestClient]) -> None:
    fields = {"xdf_max_streams": 2, "xdf_max_chunks": 30, "xdf_max_samples": 1000,
              "xdf_max_clock_offsets": 7, "xdf_max_decoded_bytes": 500_000,
              "xdf_max_channels": 16, "xdf_max_header_bytes": 100_000}
    tight = client_with(**fields)
    limits = xdf_import.limits(tight.app.state.settings)  # type: ignore[attr-defined]
    assert {f"xdf_{k}": v for k, v in asdict(limits).items()} == fields
    sid = _session(tight)
    three = write_xdf([xdf_hostile.small_stream(f"s{i}") for i in range(3)])
    _refused(_post(tight, sid, three), "more than 2 streams", "xdf_max_streams")
    assert _post(tight, sid, write_xdf([xdf_hostile.small_stream(n=1000)])).status_code == 201
    # A reader that runs past its time is stopped and the file refused.
    slow = client_with(xdf_parse_seconds=0.001)
    _refused(_post(slow, _session(slow), write_xdf([xdf_hostile.small_stream()])),
             "longer than 0.001 s", "xdf_parse_seconds")


_TICKS_SEQ_LAST = [*TICK_CHANNEL_NAMES[1:], "seq"]


#: Spoiled fields of an ExoskeletonTicks stream (`xdf_hostile.tick_stream`) that gave 500
#: or stored NaN, and what the refusal says (the other checks: test_xdf_child.py).
_SPOILED: list[tuple[dict[str, Any], str]] = [
    ({"fmt": "string", "seq": ["x"] * 20}, "seq channel holds strings"),
    ({"seq": [1000.0] * 19 + [math.nan]}, "sample 19 has seq nan"),
    ({"labels": _TICKS_SEQ_LAST, "channels": 3}, "declares 3 channels but labels 15"),
    ({"srate": "NaN"}, "nominal_srate 'NaN'"),
    ({"stamps": [50.0] * 19 + [math.inf]}, "sample 19 has the time stamp inf"),
]


def test_every_field_of_a_tick_stream_is_checked(client: TestClient, db_url: str) -> None:
    # Issue 28: an ExoskeletonTicks stream with text or NaN in seq, or fewer channels
    # than its labels, answered 500 in alignment; a NaN rate or time stamp was stored as
    # NaN in SQLite's JSON. The session has trials with ticks, so alignment would run.
    made = _session_with_two_trials(db_url)
    for spoiled, words in _SPOILED:
        _refused(_post(client, made["session"], xdf_hostile.tick_stream(**spoiled)), words)
    assert client.get(f"/api/sessions/{made['session']}/xdf").json() == []
    # Unspoiled: seq 1000-1019 are the first trial's ticks, stored at LSL 605 s on, and
    # stamped 50 s on in the file: its clock is 555 s behind ours.
    r = _post(client, made["session"], xdf_hostile.tick_stream())
    assert r.status_code == 201, r.text
    assert r.json()["streams"][0]["offset_ms"] == pytest.approx(-555_000.0, abs=1e-3)


@pytest.mark.parametrize("db_url", ["sqlite", "postgresql"], indirect=True)
def test_non_finite_numbers_never_reach_the_database(client: TestClient, db_url: str) -> None:
    # Issue 28: on PostgreSQL a NaN rate or time stamp answered 500 (`Token "NaN" is
    # invalid`); SQLite stored it as non-standard JSON.
    sid = _session(client)
    _refused(_post(client, sid, xdf_hostile.tick_stream(srate="nan")), "finite number")
    _refused(_post(client, sid, write_xdf([XdfStream(
        "EMG", "EMG", ["a"], 100.0, "double64", [1.0, math.nan], [[0.0], [1.0]])])),
        "sample 1 has the time stamp nan")
    # Values themselves may be NaN (a dropped EMG sample): they are not summarised.
    ok = write_xdf([XdfStream("EMG", "EMG", ["a"], 100.0, "double64", [1.0, 2.0],
                              [[math.nan], [1.0]])])
    assert _post(client, sid, ok).status_code == 201
    (stored,) = client.get(f"/api/sessions/{sid}/xdf").json()
    assert stored["streams"][0]["first_time"] == 1.0


def test_a_valid_2_mb_recording_is_accepted(client: TestClient) -> None:
    # Issue 23: 413, because the larger upload limit applied to one route only.
    n = int(2.0e6 / (9 + 8 * 8))
    rows = np.random.default_rng(1).normal(size=(n, 8)).tolist()
    data = write_xdf([XdfStream("EMG", "EMG", [f"ch{i}" for i in range(8)], 200.0,
                                "double64", [100.0 + i / 200 for i in range(n)], rows)])
    assert len(data) > client.app.state.settings.max_body_bytes  # type: ignore[attr-defined]
    sid = _session(client)
    r = _post(client, sid, data)
    assert r.status_code == 201, r.text
    assert r.json()["size_bytes"] == len(data)
    assert r.json()["streams"][0]["samples"] == n
    # A JSON body of the same size is still refused: the upload limit is for files.
    r = client.post("/api/studies", content=b'{"name": "' + b"x" * len(data) + b'"}',
                    headers={"content-type": "application/json"})
    assert r.status_code == 413


def test_time_stamps_and_clock_offsets_stay_in_a_plausible_range(
        client: TestClient, db_url: str) -> None:
    # Issue 28: a tick stream stamped 1.7e308 whose seq matched stored ticks was accepted
    # (201) and its offset_ms, 1.7e308 s x 1000, stored as Infinity. Time stamps and
    # clock offsets beyond 1e10 s (317 years) are refused where they are read.
    made = _session_with_two_trials(db_url)
    sid = made["session"]
    _refused(_post(client, sid, xdf_hostile.offset_overflow()),
             "sample 0 has the time stamp 1.7e+308", "1e+10 s")
    far = write_xdf([XdfStream("EMG", "EMG", ["a"], 100.0, "double64", [1.0, 2.0],
                               [[0.0], [1.0]], clock_offsets=[(1.0, 1e300)])])
    _refused(_post(client, sid, far), "clock offset (1.0, 1e+300)", "1e+10 s")
    assert client.get(f"/api/sessions/{sid}/xdf").json() == []
    # Just inside the range: stored, every number finite.
    r = _post(client, sid, xdf_hostile.tick_stream(stamps=[9.9e9] * 20))
    assert r.status_code == 201, r.text
    assert r.json()["streams"][0]["offset_ms"] == pytest.approx((9.9e9 - 605.0) * 1000)


def test_the_stored_summary_is_checked_once_before_it_is_stored() -> None:
    # The one check at the storage boundary: whatever a later change computes, a
    # non-finite number or a summary beyond xdf_max_summary_bytes is not stored.
    def one(**changed: Any) -> XdfStreamSummary:
        return XdfStreamSummary(**{
            "stream_id": 3, "name": "ExoStudy", "type": "ExoskeletonTicks",
            "channel_count": 1, "labelled_channels": 1, "nominal_srate": 100.0,
            "samples": 2, "first_time": 1.0, "last_time": 2.0, "channels": ["seq"],
            "exostudy": True, "trial_ids": [], **changed})
    assert xdf_import.storable([one(offset_ms=5.0)], 10_000)[0]["offset_ms"] == 5.0
    for field_name in ("offset_ms", "first_time", "nominal_srate"):
        with pytest.raises(XdfError, match=f"stream 3: {field_name} is inf"):
            xdf_import.storable([one(**{field_name: math.inf})], 10_000)
    with pytest.raises(XdfError, match=r"more than 300 bytes .*xdf_max_summary_bytes"):
        xdf_import.storable([one()] * 2, 300)


#: What the summary of a stream may take stored, as JSON: its name, type and source id
#: (200 characters each), xdf_summary_channels labels of 64 characters, and numbers.
_STREAM_JSON_BYTES = 3 * 200 + 64 * 68 + 400


def test_a_flood_of_channel_labels_keeps_the_summary_small(client: TestClient) -> None:
    # Issue 28: 96 headers of 65,536 labelled channels (63 MB) were accepted with a 25 MB
    # summary stored, 19 MB a GET, and the server 400 MB larger while reading it. Here
    # 24 headers of 2,048 labels (2.6 MB; 1.4 MB of summary before): the summary keeps
    # 64 labels a stream and the count.
    data = xdf_hostile.label_flood(24, 2048)
    sid = _session(client)
    r = _post(client, sid, data)
    assert r.status_code == 201, r.text
    assert len(r.content) < 25 * _STREAM_JSON_BYTES, len(r.content)
    flood = [s for s in r.json()["streams"] if s["stream_id"] >= 100]
    assert len(flood) == 24
    for s in flood:
        assert s["channel_count"] == s["labelled_channels"] == 2048
        assert s["channels"] == [f"channel-label-{c}" for c in range(64)]
    for _ in range(2):
        assert _post(client, sid, data).status_code == 201
    # Listing three such files reads neither the files nor more than their summaries.
    tracemalloc.start()
    try:
        listing = client.get(f"/api/sessions/{sid}/xdf")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert listing.status_code == 200 and len(listing.json()) == 3
    assert len(listing.content) < 3 * 25 * _STREAM_JSON_BYTES, len(listing.content)
    assert peak < 4_000_000, peak


def test_channels_headers_and_the_summary_are_bounded_by_settings(
        client: TestClient, client_with: Callable[..., TestClient]) -> None:
    # The review's stream shape, 65,536 channels, is beyond the default channel limit.
    wide = write_xdf([xdf_hostile.small_stream()]) + chunk(2, struct.pack("<I", 9) + header_xml(
        "wide", "EEG", 65_536, 0, "int8"))
    _refused(_post(client, _session(client), wide), "channel_count '65536'",
             "xdf_max_channels")
    tight = client_with(xdf_max_channels=8, xdf_max_header_bytes=4096,
                        xdf_max_summary_bytes=4096, xdf_summary_channels=2)
    sid = _session(tight)

    def stream(labels: list[str], name: str = "EMG") -> XdfStream:
        return XdfStream(name, "EMG", labels, 100.0, "double64", [1.0, 2.0],
                         [[0.0] * len(labels)] * 2)
    _refused(_post(tight, sid, write_xdf([stream([f"c{i}" for i in range(9)])])),
             "channel_count '9'", "from 1 to 8", "xdf_max_channels")
    _refused(_post(tight, sid, write_xdf([stream(["a", "b" * 5000])])),
             "stream header of 5", "at most 4096", "xdf_max_header_bytes")
    many = write_xdf([stream(["a"], f"s{i}-" + "n" * 150) for i in range(20)])
    _refused(_post(tight, sid, many), "more than 4096 bytes", "xdf_max_summary_bytes")
    assert tight.get(f"/api/sessions/{sid}/xdf").json() == []
    r = _post(tight, sid, write_xdf([stream(["x" * 100, "b", "c"])]))
    assert r.status_code == 201, r.text
    (s,) = r.json()["streams"]
    assert s["channels"] == ["x" * 64, "b"] and s["labelled_channels"] == 3
