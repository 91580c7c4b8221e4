"""EMG files beyond their rows: an erasure deletes them, a reused id never overwrites an
old file, and a server killed mid-recording keeps every whole chunk of the `.part`
(regressions: files of erased participants stayed; a killed recording stayed
"recording" with 0 samples and its data in `.part` forever)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.db.emg import EmgRecording
from backend.emg import recordings, recovery, store
from tests.backend.emg.test_emg_api import MONTAGE, _edf


def _import(client: TestClient, sess: int) -> dict[str, Any]:
    data, _ = _edf(["ES-L lumbar", "ES-R lumbar", "GM-L"], seconds=2)
    r = client.post(f"/api/sessions/{sess}/emg/edf", files={"file": ("a.edf", data)},
                    data={"marker": "sync"})
    assert r.status_code == 201, r.text
    return dict(r.json())


def _ready(client: TestClient, name: str = "EMG") -> tuple[int, int]:
    study = client.post("/api/studies", json={"name": name}).json()["id"]
    pid = client.post(f"/api/studies/{study}/participants", json={"code": "P1"}).json()["id"]
    sess = client.post(f"/api/participants/{pid}/sessions",
                       json={"kind": "evaluation", "precompression_pct": 25}).json()["id"]
    client.put(f"/api/studies/{study}/emg-montage", json=MONTAGE)
    client.post(f"/api/sessions/{sess}/markers", json={"label": "sync"})
    return study, sess


def test_erasure_deletes_the_files_and_a_reused_id_never_overwrites(
        client: TestClient, settings: Settings) -> None:
    study, sess = _ready(client)
    rec = _import(client, sess)
    path = store.recording_path(settings, rec["id"])
    assert path.exists()
    pid = client.get(f"/api/studies/{study}/participants").json()[0]["id"]
    r = client.post(f"/api/participants/{pid}/withdraw")
    assert r.status_code == 200 and r.json()["outcome"] == "erased"
    assert not path.exists()
    folder = store.emg_folder(settings)
    with client.app.state.sessions() as db:  # type: ignore[attr-defined]
        assert recovery.orphans(db, folder) == []
    # An erasure whose deletion failed left a file under an id the database gives again.
    stale = b"an old recording's bytes"
    path.write_bytes(stale)
    _study2, sess2 = _ready(client, "EMG 2")
    rec2 = _import(client, sess2)
    new = store.recording_path(settings, rec2["id"])
    assert store.file_sha256(new) == rec2["sha256"]
    with client.app.state.sessions() as db:  # type: ignore[attr-defined]
        found = recovery.orphans(db, folder)
    if rec2["id"] == rec["id"]:  # SQLite reused the id: the old file was moved aside
        assert len(found) == 1 and found[0].read_bytes() == stale
    else:
        assert found == [path] and path.read_bytes() == stale


def _written_then_killed(client: TestClient, settings: Settings
                         ) -> tuple[int, Path, Path, np.ndarray, np.ndarray]:
    """A live recording of two whole chunks and 123 buffered rows whose server is then
    gone (its writer never closed): its id, its file and `.part`, the timestamps and
    samples appended."""
    _study, sess = _ready(client)
    with client.app.state.sessions() as db:  # type: ignore[attr-defined]
        montage = recordings.session_montage(db, sess)
        w = recordings.RecordingWriter(db, settings, sess, montage, "lsl", 2000.0)
        n = store.CHUNK_ROWS * 2 + 123
        t = np.arange(n) / 2000.0
        x = np.random.default_rng(4).normal(0, 1e-4, (n, 3))
        w.append(t, x)
        rid = w.row.id
    return rid, w.path, w.path.with_name(w.path.name + ".part"), t, x


def test_a_killed_recording_keeps_its_whole_chunks_at_start_up(
        client: TestClient, settings: Settings) -> None:
    from backend.main import create_app

    rid, path, part, t, x = _written_then_killed(client, settings)
    # The kill: the process dies with the buffered rows; a chunk was half written.
    with open(part, "ab") as f:
        f.write(b"\x40\x00\x00\x00{\"rows\":10000,\"t_b")
    quiet = settings.model_copy(update={"device_spawn_simulator": False})
    with TestClient(create_app(quiet)) as c2, \
            c2.app.state.sessions() as db:  # type: ignore[attr-defined]
            row = db.get(EmgRecording, rid)
            assert row is not None
            assert row.status == "interrupted"
            assert row.n_samples == 2 * store.CHUNK_ROWS
            assert "interrupted" in row.quality["flags"]
            assert "cut" in row.quality["recovery"]
            assert row.t_start == 0.0 and row.t_end == (2 * store.CHUNK_ROWS - 1) / 2000.0
            got_t, got_x = store.read_window(path)
            np.testing.assert_array_equal(got_t, t[:2 * store.CHUNK_ROWS])
            np.testing.assert_allclose(got_x, x[:2 * store.CHUNK_ROWS].astype(np.float32))
            assert store.file_sha256(path) == row.sha256
            assert not part.exists()


def test_a_killed_recording_whose_chunk_is_damaged_keeps_what_reads_back(
        client: TestClient, settings: Settings) -> None:
    """A `.part` whose second chunk is framed whole but does not read back (a plane's
    compression flag changed): the server still starts, and keeps the first chunk."""
    from backend.main import create_app

    rid, path, part, t, _x = _written_then_killed(client, settings)
    data = part.read_bytes()
    second = data.index(b'"x_planes":[[', data.index(b'"x_planes":[[') + 1)
    flag = data.index(b",", second + len(b'"x_planes":[[')) + 1  # the first plane's
    assert data[flag:flag + 1] == b"0"
    part.write_bytes(data[:flag] + b"1" + data[flag + 1:])
    quiet = settings.model_copy(update={"device_spawn_simulator": False})
    with TestClient(create_app(quiet)) as c2, \
            c2.app.state.sessions() as db:  # type: ignore[attr-defined]
            row = db.get(EmgRecording, rid)
            assert row is not None and row.status == "interrupted"
            assert row.n_samples == store.CHUNK_ROWS
            got_t, _got_x = store.read_window(path)
            np.testing.assert_array_equal(got_t, t[:store.CHUNK_ROWS])
