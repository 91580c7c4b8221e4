"""The EMG recording file: what goes in comes out (NaN included), in chunks, private,
and a damaged file is refused rather than misread."""

from __future__ import annotations

import math
import stat
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from backend.emg import store


def _write(path: Path, blocks: list[tuple[np.ndarray, np.ndarray]], labels: list[str]
           ) -> tuple[str, int]:
    w = store.EmgWriter(path, labels, 2000.0)
    for t, x in blocks:
        w.append(t, x)
    return w.close()


@settings(max_examples=25, deadline=None)
@given(sizes=st.lists(st.integers(0, 25_000), min_size=1, max_size=4),
       channels=st.integers(1, 5), seed=st.integers(0, 2**32 - 1))
def test_round_trip_is_exact_in_float32(tmp_path_factory: pytest.TempPathFactory,
                                        sizes: list[int], channels: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    path = tmp_path_factory.mktemp("s") / "1.emgc"
    blocks, n = [], 0
    for size in sizes:
        t = 100.0 + np.arange(n, n + size) / 2000.0
        x = rng.normal(0, 1e-4, (size, channels))
        if size:
            x[rng.integers(size), 0] = np.nan
        blocks.append((t, x))
        n += size
    sha, rows = _write(path, blocks, [f"c{i}" for i in range(channels)])
    assert rows == n and sha == store.file_sha256(path)
    t_all = np.concatenate([b[0] for b in blocks])
    x_all = np.concatenate([b[1] for b in blocks]).astype(np.float32)
    got_t, got_x = store.read_window(path)
    np.testing.assert_array_equal(got_t, t_all)
    np.testing.assert_array_equal(got_x, x_all.astype(np.float64))  # NaN == NaN here
    for t, _ in store.iter_chunks(path):
        assert t.size <= store.CHUNK_ROWS


def test_a_window_reads_only_its_rows_and_the_file_is_private(tmp_path: Path) -> None:
    path = tmp_path / "emg" / "7.emgc"
    t = np.arange(50_000) / 2000.0
    x = np.column_stack([t, -t])
    _write(path, [(t, x)], ["a", "b"])
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert stat.S_IMODE(path.parent.stat().st_mode) == 0o700
    assert not path.with_name("7.emgc.part").exists()
    wt, wx = store.read_window(path, 10.0, 12.0)
    assert wt[0] == 10.0 and wt.size == 4000
    np.testing.assert_allclose(wx[:, 1], -wt, rtol=1e-6)
    assert store.read_header(path).labels == ("a", "b")


def test_an_hour_of_16_channels_is_never_held_whole(tmp_path: Path) -> None:
    """The writer buffers at most one chunk: its buffers stay under 2 chunks of rows
    while a minute of 16 channels at 2 kHz is appended in 0.1 s pieces."""
    w = store.EmgWriter(tmp_path / "1.emgc", [str(i) for i in range(16)], 2000.0)
    block = np.zeros((200, 16))
    most = 0
    for k in range(600):
        w.append(k * 0.1 + np.arange(200) / 2000.0, block)
        most = max(most, sum(len(b) for b in w._x))
    w.close()
    assert most < 2 * store.CHUNK_ROWS


def test_damaged_files_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "1.emgc"
    _write(path, [(np.arange(100) / 2000.0, np.ones((100, 2)))], ["a", "b"])
    data = path.read_bytes()
    path.write_bytes(data[:-10])
    with pytest.raises(store.EmgStoreError, match="ends in the middle"):
        store.read_window(path)
    path.write_bytes(b"not ours" + data[8:])
    with pytest.raises(store.EmgStoreError, match="not an ExoStudy EMG"):
        store.read_header(path)


def test_wrong_shapes_are_refused_and_abort_leaves_nothing(tmp_path: Path) -> None:
    w = store.EmgWriter(tmp_path / "1.emgc", ["a", "b"], 2000.0)
    with pytest.raises(store.EmgStoreError, match=r"shape \(n, 2\)"):
        w.append(np.arange(3), np.ones((3, 3)))
    with pytest.raises(store.EmgStoreError, match="3 timestamps for 2 samples"):
        w.append(np.arange(3), np.ones((2, 2)))
    w.abort()
    assert list(tmp_path.iterdir()) == []


@settings(max_examples=40, deadline=None)
@given(blocks=st.lists(st.lists(st.one_of(
    st.floats(-1e6, 1e6), st.sampled_from([np.nan, np.inf, -np.inf])), max_size=6),
    min_size=1, max_size=6))
def test_span_is_the_finite_stamps_extremes_whatever_the_blocks(
        tmp_path_factory: pytest.TempPathFactory, blocks: list[list[float]]) -> None:
    """The span as it was taken block by block from the finite stamps only (the fast
    path of wholly finite blocks gives the same)."""
    w = store.EmgWriter(tmp_path_factory.mktemp("s") / "1.emgc", ["a"], 2000.0)
    first: float | None = None
    last: float | None = None
    for stamps in blocks:
        t = np.asarray(stamps, dtype=np.float64)
        w.append(t, np.zeros((t.size, 1)))
        fin = t[np.isfinite(t)]
        if fin.size:
            lo, hi = float(fin.min()), float(fin.max())
            first = lo if first is None else min(first, lo)
            last = hi if last is None else max(last, hi)
    w.abort()
    assert (w.first_t, w.last_t) == (first, last)


def _chunk_headers(path: Path) -> list[dict[str, object]]:
    """The JSON header of every chunk, read with the file's own framing."""
    heads = []
    with open(path, "rb") as f:
        store._header(f)
        while (doc := store._read_json(f)) is not None:
            heads.append(doc)
            f.seek(int(doc["t_bytes"]) + int(doc["x_bytes"]), 1)
    return heads


def test_noise_bytes_are_stored_as_they_are_and_the_rest_compressed(tmp_path: Path) -> None:
    """The low three bytes of a noisy float32 sample do not compress: stored as they are
    (no CPU spent on them); its exponent byte, and every byte of a flat channel, are
    compressed. What goes in comes out either way."""
    rng = np.random.default_rng(3)
    t = 10.0 + np.arange(12_000) / 2000.0
    for x, expected in ((rng.normal(0, 1e-4, (12_000, 3)), [0, 0, 0, 1]),
                        (np.zeros((12_000, 3)), [1, 1, 1, 1])):
        path = tmp_path / f"{expected[0]}.emgc"
        _write(path, [(t, x)], ["a", "b", "c"])
        assert path.read_bytes().startswith(b"EXOEMG2\n")
        heads = _chunk_headers(path)
        assert len(heads) == 2  # 10,000 rows, then the 2,000 the close wrote
        assert [p[1] for p in heads[0]["x_planes"]] == expected  # type: ignore[attr-defined]
        got_t, got_x = store.read_window(path)
        np.testing.assert_array_equal(got_t, t)
        np.testing.assert_array_equal(got_x, x.astype(np.float32).astype(np.float64))


def _first_format(path: Path, t: np.ndarray, x: np.ndarray) -> None:
    """A file as the first version wrote it: every plane of an array in one zlib stream,
    no plane layout in the chunk header (written here independently of the writer)."""
    import json
    import struct
    import zlib

    def packed(a: np.ndarray) -> bytes:
        return zlib.compress(a.view(np.uint8).reshape(-1, a.dtype.itemsize).T.tobytes())

    def framed(doc: dict[str, object]) -> bytes:
        head = json.dumps(doc).encode()
        return struct.pack("<I", len(head)) + head

    tb, xb = packed(np.ascontiguousarray(t)), packed(np.ascontiguousarray(x))
    path.write_bytes(b"EXOEMG1\n" + framed({"n_channels": x.shape[1], "fs": 2000.0,
                                            "labels": ["a", "b"]})
                     + framed({"rows": len(t), "t_bytes": len(tb), "x_bytes": len(xb),
                               "t_min": float(t[0]), "t_max": float(t[-1])}) + tb + xb)


def test_a_file_of_the_first_format_is_still_read(tmp_path: Path) -> None:
    path = tmp_path / "old.emgc"
    t = 5.0 + np.arange(300) / 2000.0
    x = np.random.default_rng(4).normal(0, 1e-4, (300, 2)).astype(np.float32)
    _first_format(path, t, x)
    got_t, got_x = store.read_window(path)
    np.testing.assert_array_equal(got_t, t)
    np.testing.assert_array_equal(got_x, x.astype(np.float64))
    ((chunk_t, chunk_x),) = list(store.iter_chunks(path))
    np.testing.assert_array_equal(chunk_t, t)
    np.testing.assert_array_equal(chunk_x, x)


def test_a_plane_layout_that_does_not_match_its_bytes_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "1.emgc"
    _write(path, [(np.arange(100) / 2000.0, np.ones((100, 2)))], ["a", "b"])
    data = path.read_bytes()
    # One more byte claimed by the samples' first plane than the chunk holds.
    (head,) = _chunk_headers(path)
    n = head["x_planes"][0][0]  # type: ignore[index]
    bad = data.replace(f'"x_planes":[[{n},'.encode(), f'"x_planes":[[{n + 1},'.encode())
    assert bad != data
    path.write_bytes(bad)
    with pytest.raises(store.EmgStoreError, match="byte-plane layout"):
        store.read_window(path)


def _frames(path: Path) -> tuple[bytes, list[tuple[dict[str, Any], bytes]]]:
    """A written file's magic and header frame, and each chunk's header and payload."""
    import json
    import struct

    data = path.read_bytes()
    at = 8
    (n,) = struct.unpack_from("<I", data, at)
    head_end = at + 4 + n
    chunks, at = [], head_end
    while at < len(data):
        (n,) = struct.unpack_from("<I", data, at)
        doc = json.loads(data[at + 4:at + 4 + n])
        size = doc["t_bytes"] + doc["x_bytes"]
        chunks.append((doc, data[at + 4 + n:at + 4 + n + size]))
        at += 4 + n + size
    return data[:head_end], chunks


def _rebuilt(path: Path, head: bytes, chunks: list[tuple[dict[str, Any], bytes]]) -> None:
    import json
    import struct

    out = head
    for doc, payload in chunks:
        raw = json.dumps(doc, allow_nan=True).encode()
        out += struct.pack("<I", len(raw)) + raw + payload
    path.write_bytes(out)


def _damaged(path: Path, how: str) -> None:
    """`path` rewritten with one kind of damage in its first chunk."""
    import json
    import struct
    import zlib

    head, chunks = _frames(path)
    doc, payload = chunks[0]
    if how == "negative-size-unindexed":  # a seek back onto its own header
        doc.update(t_min=None, t_max=None, t_bytes=-(len(json.dumps(doc)) + 4))
    elif how == "huge-size":
        doc["t_bytes"] = 10**15
    elif how == "rows-missing":
        del doc["rows"]
    elif how == "time-range-text":
        doc["t_max"] = "zz"
    elif how == "size-infinite":
        doc["t_bytes"] = math.inf
    elif how == "flag-flipped":
        doc["x_planes"][0][1] = 1 - doc["x_planes"][0][1]
    elif how == "raw-byte-changed":
        start = doc["t_bytes"]  # the samples' first plane, stored as it is
        assert doc["x_planes"][0][1] == 0
        payload = payload[:start] + bytes([payload[start] ^ 1]) + payload[start + 1:]
    elif how == "bomb":  # a small chunk claiming a plane that inflates past its size
        bomb = zlib.compress(bytes(50_000_000), 9)
        t_len = doc["t_bytes"]
        x_planes = [[len(bomb), 1, 0], *doc["x_planes"][1:]]
        payload = payload[:t_len] + bomb + payload[t_len + doc["x_planes"][0][0]:]
        doc.update(x_planes=x_planes, x_bytes=sum(p[0] for p in x_planes))
    elif how == "header-channels":
        head = head[:8] + _frame({"n_channels": 10**30, "fs": 2000.0, "labels": ["a"]})
    elif how == "header-labels":
        head = head[:8] + _frame({"n_channels": 2, "fs": 2000.0, "labels": 5})
    chunks[0] = (doc, payload)
    _rebuilt(path, head, chunks)
    del struct


def _frame(doc: dict[str, Any]) -> bytes:
    import json
    import struct

    raw = json.dumps(doc).encode()
    return struct.pack("<I", len(raw)) + raw


DAMAGE = ["negative-size-unindexed", "huge-size", "rows-missing", "time-range-text",
          "size-infinite", "flag-flipped", "raw-byte-changed", "bomb", "header-channels",
          "header-labels"]


@pytest.mark.parametrize("how", DAMAGE)
def test_a_damaged_or_hostile_file_is_refused_by_every_reader(tmp_path: Path,
                                                              how: str) -> None:
    """Whatever the damage, every reader raises `EmgStoreError` (which the API answers as
    a 4xx and recovery keeps what reads back from): never another exception, a loop,
    or an allocation the file's size does not justify."""
    path = tmp_path / "1.emgc"
    rng = np.random.default_rng(5)
    _write(path, [(np.arange(12_000) / 2000.0, rng.normal(0, 1e-4, (12_000, 2)))],
           ["a", "b"])
    head = len(_frames(path)[0])
    _damaged(path, how)
    for read in (lambda: store.read_window(path), lambda: list(store.iter_chunks(path))):
        with pytest.raises(store.EmgStoreError):
            read()
    try:  # a window after the data: its chunks may be skipped unread, never misread
        got_t, _x = store.read_window(path, 100.0, 200.0)
        assert got_t.size == 0
    except store.EmgStoreError:
        pass
    if how.startswith("header"):
        with pytest.raises(store.EmgStoreError):
            store.whole_length(path)
    else:  # recovery keeps the header alone: the first chunk does not read back
        assert store.whole_length(path) == (head, 0)


@settings(max_examples=60, deadline=None)
@given(flips=st.lists(st.tuples(st.integers(0, 10**9), st.integers(1, 255)),
                      min_size=1, max_size=3))
def test_changed_bytes_read_back_or_raise_the_stores_error(
        tmp_path_factory: pytest.TempPathFactory, flips: list[tuple[int, int]]) -> None:
    path = tmp_path_factory.mktemp("f") / "1.emgc"
    t = np.arange(3_000) / 2000.0
    x = np.random.default_rng(6).normal(0, 1e-4, (3_000, 2))
    _write(path, [(t, x)], ["a", "b"])
    data = bytearray(path.read_bytes())
    for at, mask in flips:
        data[at % len(data)] ^= mask
    path.write_bytes(bytes(data))
    try:
        got_t, got_x = store.read_window(path)
    except store.EmgStoreError:
        return
    # Read back whole: then it is what was written (a changed header byte that still
    # parses, e.g. in a label, leaves the data as it was).
    np.testing.assert_array_equal(got_t, t)
    np.testing.assert_array_equal(got_x, x.astype(np.float32).astype(np.float64))
