"""XDF uploads cannot exhaust memory (issue 23: a 573-byte file declaring 30 million
samples took 2.5 GB in pyxdf, one declaring 250 million channels 4.5 GB): declared sizes
are checked against the file's own bytes before pyxdf runs, pyxdf runs in a child with
a memory ceiling, and a real 2 MB recording fits the upload limit."""

from __future__ import annotations

import resource
import struct
from pathlib import Path

import numpy as np
import pytest
import pyxdf
from fastapi.testclient import TestClient

from backend.lab import xdf_limits
from tests.backend.lab.xdf_writer import XdfStream, _chunk, write_xdf


def _header(sid: int, channels: int, fmt: str) -> bytes:
    xml = (f'<?xml version="1.0"?><info><name>crafted</name><type>EEG</type>'
           f"<channel_count>{channels}</channel_count><nominal_srate>100</nominal_srate>"
           f"<channel_format>{fmt}</channel_format></info>")
    return _chunk(2, struct.pack("<I", sid) + xml.encode())


def _declaring(samples: int, channels: int = 1, fmt: str = "string") -> bytes:
    """A tiny file whose one Samples chunk declares `samples` samples and holds one."""
    one = bytes([8]) + struct.pack("<d", 1.0) + (bytes([1, 1]) + b"x") * channels \
        if fmt == "string" else bytes([8]) + struct.pack("<d", 1.0) + bytes(8 * channels)
    body = struct.pack("<I", 1) + bytes([4]) + struct.pack("<I", samples) + one
    return b"XDF:" + _chunk(1, b"<info><version>1.0</version></info>") + \
        _header(1, channels, fmt) + _chunk(3, body)


def _session(client: TestClient) -> int:
    sid = client.post("/api/studies", json={"name": "X"}).json()["id"]
    pid = client.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"]
    r = client.post(f"/api/participants/{pid}/sessions",
                    json={"kind": "evaluation", "precompression_pct": 25})
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _recording(megabytes: float) -> bytes:
    """A valid XDF file of about `megabytes`: 8 double channels at 200 Hz."""
    n = int(megabytes * 1e6 / (9 + 8 * 8))
    rows = np.random.default_rng(1).normal(size=(n, 8)).tolist()
    emg = XdfStream("EMG", "EMG", [f"ch{i}" for i in range(8)], 200.0, "double64",
                    [100.0 + i / 200 for i in range(n)], rows)
    return write_xdf([emg])


def test_a_file_declaring_30_million_samples_is_refused_by_the_check() -> None:
    data = _declaring(30_000_000)
    assert len(data) < 600
    with pytest.raises(xdf_limits.XdfRefusedError, match="30000000 samples"):
        xdf_limits.check(data)


def test_a_header_declaring_250_million_channels_is_refused() -> None:
    data = b"XDF:" + _header(1, 250_000_000, "float32")
    with pytest.raises(xdf_limits.XdfRefusedError, match="channel_count"):
        xdf_limits.check(data)


def test_the_decoded_size_limit_applies_to_files_that_do_hold_their_samples() -> None:
    data = _recording(0.2)
    plan = xdf_limits.check(data)
    assert plan.readable_bytes == len(data) and not plan.truncated
    with pytest.raises(xdf_limits.XdfRefusedError, match="decode to more than"):
        xdf_limits.check(data, max_decoded_bytes=plan.decoded_bytes - 1)


def test_a_file_cut_short_is_read_up_to_its_last_whole_chunk() -> None:
    data = _recording(0.05)
    cut = data[:-10]
    plan = xdf_limits.check(cut)
    assert plan.truncated and plan.readable_bytes < len(cut)


def test_the_child_process_cannot_grow_past_its_ceiling() -> None:
    # The second layer, without the first: pyxdf itself given the crafted file (2.5 GB
    # in the server before) runs out of its 400 MB in the child, which pyxdf reports as
    # a damaged chunk; the server's own memory does not grow.
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    streams = xdf_limits.load(_declaring(30_000_000), address_space=400 * 1024**2)
    assert all(len(s["time_stamps"]) == 0 for s in streams)
    grown_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
    assert grown_kb < 100 * 1024


def test_the_child_reads_what_pyxdf_reads(tmp_path: Path) -> None:
    data = _recording(0.1)
    path = tmp_path / "r.xdf"
    path.write_bytes(data)
    direct, _ = pyxdf.load_xdf(str(path), dejitter_timestamps=False)
    child = xdf_limits.load(data)
    np.testing.assert_array_equal(child[0]["time_series"], direct[0]["time_series"])
    np.testing.assert_array_equal(child[0]["time_stamps"], direct[0]["time_stamps"])


def test_the_api_refuses_crafted_files_before_parsing(
        client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    def never(*_: object, **__: object) -> None:
        raise AssertionError("pyxdf ran on a file the check should have refused")

    monkeypatch.setattr(xdf_limits, "load", never)
    sid = _session(client)
    for data in (_declaring(30_000_000), b"XDF:" + _header(1, 250_000_000, "float32"),
                 _declaring(5_000_000, channels=100, fmt="double64")):
        r = client.post(f"/api/sessions/{sid}/xdf",
                        files={"file": ("crafted.xdf", data, "application/octet-stream")})
        assert r.status_code == 422, r.text
        assert r.json()["detail"][0]["loc"] == ["body", "file"]
    assert client.get(f"/api/sessions/{sid}/xdf").json() == []


def test_a_valid_2_mb_recording_is_accepted(client: TestClient) -> None:
    # Issue 23: 413, because the larger upload limit applied to one route only.
    data = _recording(2.0)
    assert len(data) > client.app.state.settings.max_body_bytes  # type: ignore[attr-defined]
    sid = _session(client)
    r = client.post(f"/api/sessions/{sid}/xdf",
                    files={"file": ("emg.xdf", data, "application/octet-stream")})
    assert r.status_code == 201, r.text
    assert r.json()["size_bytes"] == len(data)
    assert r.json()["streams"][0]["samples"] == int(2.0e6 / (9 + 8 * 8))
    # A JSON body of the same size is still refused: the upload limit is for files.
    r = client.post("/api/studies", content=b'{"name": "' + b"x" * len(data) + b'"}',
                    headers={"content-type": "application/json"})
    assert r.status_code == 413
