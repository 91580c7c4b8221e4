"""EMG recordings as files beside the database: chunked, compressed per chunk, float32.

Why files: an hour of 16 channels at 2 kHz is 230 MB as float32. In a database row it
would bloat every backup and, with SQLite or PostgreSQL alike, be read whole into the
server's memory. Here each recording is one file `<id>.emgc` in the EMG folder (by
default `emg/` beside the SQLite database, or in the data folder when the database is
PostgreSQL: the files never go into PostgreSQL), mode 0600 in a 0700 folder; the database
holds one row per recording (`backend.db.emg.EmgRecording`) with its sha256.

Format (ExoStudy's own; numpy and zlib only, no new dependency): the magic line
`EXOEMG2\\n`, a header (4-byte little-endian length, JSON: channel count, nominal rate,
labels), then chunks, each a 4-byte length and a JSON chunk header (rows, byte lengths,
byte-plane layout) followed by the timestamps (float64) and samples (float32,
row-major), each byte-shuffled (byte k of every value together, so the slowly changing
high bytes compress): each byte plane zlib-compressed, or stored as it is when its first
4 kB do not compress (`RAW_ABOVE`; `t_planes` and `x_planes` give each plane's stored
length and whether it is compressed). Files of the first version (`EXOEMG1\\n`) held all
planes of an array in one zlib stream; they are still read. A chunk is written when the
writer's buffer holds `CHUNK_ROWS` rows (5 s at 2 kHz), so the writer keeps at most one
chunk in memory and a reader one chunk at a time. A chunk header also holds the chunk's
time range (`t_min`, `t_max` over its finite timestamps, null when it has none): the
chunk index, so `read_window` decompresses only the chunks overlapping its window (files
written before it have no range: their timestamps are decompressed, never their
samples). The file is written as `<name>.part` and renamed when closed, so a recording
cut short by a crash is never mistaken for a finished one; every chunk is handed to the
operating system when written, so a killed server leaves whole chunks in the `.part` for
`backend.emg.recovery` to finalise.

Samples keep NaN and infinities as they came (flagged, never altered); timestamps are
the session clock minus the row's `time_offset_s` (see `backend.db.emg`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Engine

from backend.core import config
from backend.core.config import Settings, get_settings
from backend.core.data_folder import sqlite_file
from controller.private_files import make_private_dir

MAGIC = b"EXOEMG2\n"
#: Files written before byte planes could be stored as they are: read, never written.
MAGIC_V1 = b"EXOEMG1\n"
#: A byte plane whose first `_PROBE` bytes compress to more than this fraction of their
#: size is stored as it is. The low three bytes of a float32 EMG sample are noise:
#: measured on the simulated amplifier's recordings, they compress to 1.00 of their size
#: and the sign-and-exponent byte to 0.46, and zlib spent about 30 MB/s of CPU on each
#: for nothing (a third of a sped-up virtual study's EMG inlet, by profile).
RAW_ABOVE = 0.9
_PROBE = 4096
#: Rows per chunk: 10,000 rows of 16 channels is 640 kB of float32 before compression.
CHUNK_ROWS = 10_000
#: zlib level: 1 is several times faster than 6 for a few percent more bytes, so an
#: hour-long live recording costs little CPU beside the control loop.
ZLIB_LEVEL = 1
_LEN = struct.Struct("<I")
#: Largest JSON header a reader accepts (a file is ours, but a damaged one must not
#: make the reader allocate gigabytes).
_MAX_HEADER = 1 << 20
#: Bounds a reader holds the header and every chunk header to, so that a damaged or
#: hostile file can make it neither allocate without limit nor seek backwards (the
#: writer's chunks hold `CHUNK_ROWS` rows; amplifiers have at most a few hundred
#: channels).
MAX_CHUNK_ROWS = 4 * CHUNK_ROWS
MAX_CHANNELS = 1024


class EmgStoreError(ValueError):
    """A recording file is damaged or does not match what was asked of it."""


def _shuffle(arr: NDArray[Any]) -> tuple[bytes, list[list[int]]]:
    """The array's byte planes, each compressed unless a probe shows it does not
    compress; the bytes and each plane's [stored length, 1 if compressed else 0, CRC-32
    of the plane] (a plane stored as it is has no zlib checksum: the CRC finds a
    damaged one)."""
    a = np.ascontiguousarray(arr)
    parts: list[bytes] = []
    layout: list[list[int]] = []
    for plane in a.view(np.uint8).reshape(-1, a.dtype.itemsize).T:
        raw = plane.tobytes()
        probe = raw[:_PROBE]
        crc = zlib.crc32(raw)
        if probe and len(zlib.compress(probe, ZLIB_LEVEL)) > RAW_ABOVE * len(probe):
            parts.append(raw)
            layout.append([len(raw), 0, crc])
        else:
            packed = zlib.compress(raw, ZLIB_LEVEL)
            parts.append(packed)
            layout.append([len(packed), 1, crc])
    return b"".join(parts), layout


def _inflate(data: bytes, size: int) -> bytes:
    """`data` decompressed, which must give exactly `size` bytes: never more is
    allocated (a small damaged or hostile chunk cannot inflate to gigabytes)."""
    d = zlib.decompressobj()
    try:
        out = d.decompress(data, size)
        if len(out) == size and not d.eof:
            out += d.decompress(d.unconsumed_tail, 1)
    except zlib.error as exc:
        raise EmgStoreError(f"chunk does not decompress ({exc}): the file is damaged") \
            from exc
    if len(out) != size or not d.eof or d.unconsumed_tail or d.unused_data:
        raise EmgStoreError(f"chunk decompresses to other than its {size} bytes: the file "
                            "is damaged")
    return out


def _unshuffle(data: bytes, dtype: Any, n: int, planes: Any = None) -> NDArray[Any]:
    """`n` values of `dtype` from a chunk's bytes: planes as `_shuffle` laid them out, or
    (`planes` None, the first format) one zlib stream of all planes. EmgStoreError for
    anything that does not match."""
    dt = np.dtype(dtype)
    if planes is None:
        raw = _inflate(data, n * dt.itemsize)
    else:
        if (not isinstance(planes, list) or len(planes) != dt.itemsize
                or not all(isinstance(p, list) and len(p) == 3
                           and all(type(v) is int for v in p) and p[0] >= 0
                           and p[1] in (0, 1) for p in planes)
                or sum(p[0] for p in planes) != len(data)):
            raise EmgStoreError("chunk's byte-plane layout does not match its bytes: the "
                                "file is damaged")
        pieces, at = [], 0
        for length, packed, crc in planes:
            piece = data[at:at + length]
            at += length
            plane = _inflate(piece, n) if packed else piece
            if len(plane) != n or zlib.crc32(plane) != crc:
                raise EmgStoreError("a byte plane of the chunk does not match its checksum: "
                                    "the file is damaged")
            pieces.append(plane)
        raw = b"".join(pieces)  # n bytes a plane, checked: n values whichever the format
    return np.frombuffer(raw, np.uint8).reshape(dt.itemsize, n).T.copy().view(dt).ravel()


@dataclass(frozen=True, slots=True)
class _Chunk:
    """A chunk header, checked: sizes within bounds, types as written."""

    rows: int
    t_bytes: int
    x_bytes: int
    t_planes: Any
    x_planes: Any
    #: (t_min, t_max) over its finite stamps; None: no finite stamp; absent (files
    #: written before the index): `indexed` is False.
    t_range: tuple[float, float] | None
    indexed: bool


def _finite(value: Any) -> float | None:
    """`value` as a float if it is a finite JSON number (not a boolean), else None."""
    if isinstance(value, int | float) and not isinstance(value, bool) \
            and math.isfinite(value):
        return float(value)
    return None


def _count(doc: dict[str, Any], key: str, most: int) -> int:
    value = doc.get(key)
    if type(value) is not int or not 0 <= value <= most:
        raise EmgStoreError(f"chunk header's {key!r} is {value!r}: the file is damaged")
    return value


def _stored_most(raw: int, width: int) -> int:
    """The most bytes `raw` bytes in `width` planes can take stored (zlib's worst case
    for data that does not compress, with room to spare)."""
    return raw + raw // 500 + 64 * (width + 1)


def _chunk(doc: dict[str, Any], n_channels: int) -> _Chunk:
    rows = _count(doc, "rows", MAX_CHUNK_ROWS)
    t_bytes = _count(doc, "t_bytes", _stored_most(rows * 8, 8))
    x_bytes = _count(doc, "x_bytes", _stored_most(rows * 4 * n_channels, 4))
    indexed = "t_min" in doc
    t_range: tuple[float, float] | None = None
    if indexed:
        lo, hi = doc.get("t_min"), doc.get("t_max")
        if lo is not None or hi is not None:
            t_min, t_max = _finite(lo), _finite(hi)
            if t_min is None or t_max is None:
                raise EmgStoreError(f"chunk header's time range ({lo!r}, {hi!r}) is not "
                                    "two finite numbers: the file is damaged")
            t_range = (t_min, t_max)
    return _Chunk(rows, t_bytes, x_bytes, doc.get("t_planes"), doc.get("x_planes"),
                  t_range, indexed)


@dataclass(frozen=True, slots=True)
class Header:
    """What a file says about itself."""

    n_channels: int
    fs: float
    labels: tuple[str, ...]


class EmgWriter:
    """Appends blocks of (timestamps, samples) to a new recording file.

    Holds at most `CHUNK_ROWS` rows in memory; `close()` writes the rest, renames the
    file into place and returns its sha256 and row count."""

    def __init__(self, path: Path, labels: list[str], fs: float) -> None:
        if not labels:
            raise EmgStoreError("a recording needs at least one channel")
        self.path = Path(path)
        self.n_channels = len(labels)
        self.fs = float(fs)
        self.rows = 0
        #: Rows appended so far (written or buffered).
        self.appended = 0
        #: Earliest and latest finite timestamp (not the first and last row: stamps that
        #: step back or are not finite must not give a span that ends before it starts).
        self.first_t: float | None = None
        self.last_t: float | None = None
        make_private_dir(self.path.parent)
        self._part = self.path.with_name(self.path.name + ".part")
        fd = os.open(self._part, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        self._f: BinaryIO = os.fdopen(fd, "wb")
        self._sha = hashlib.sha256()
        self._t: list[NDArray[np.float64]] = []
        self._x: list[NDArray[np.float32]] = []
        self._buffered = 0
        self._write(MAGIC)
        self._record({"n_channels": self.n_channels, "fs": self.fs, "labels": list(labels)})

    def _write(self, data: bytes) -> None:
        self._f.write(data)
        self._sha.update(data)

    def _record(self, doc: dict[str, Any], *payload: bytes) -> None:
        head = json.dumps(doc, separators=(",", ":")).encode()
        self._write(_LEN.pack(len(head)) + head)
        for p in payload:
            self._write(p)

    def append(self, timestamps: NDArray[Any], samples: NDArray[Any]) -> None:
        """Add rows; `samples` (n, n_channels) in volts, `timestamps` (n,) in seconds."""
        x = np.asarray(samples, dtype=np.float32)
        t = np.asarray(timestamps, dtype=np.float64).ravel()
        if x.ndim != 2 or x.shape[1] != self.n_channels:
            raise EmgStoreError(f"samples must have shape (n, {self.n_channels}), got "
                                f"{x.shape}")
        if t.shape[0] != x.shape[0]:
            raise EmgStoreError(f"{t.shape[0]} timestamps for {x.shape[0]} samples")
        if not x.shape[0]:
            return
        lo, hi = float(t.min()), float(t.max())
        if not (math.isfinite(lo) and math.isfinite(hi)):  # both are only if every stamp is
            fin = t[np.isfinite(t)]
            lo, hi = (float(fin.min()), float(fin.max())) if fin.size else (math.nan, math.nan)
        if math.isfinite(lo):
            self.first_t = lo if self.first_t is None else min(self.first_t, lo)
            self.last_t = hi if self.last_t is None else max(self.last_t, hi)
        self._t.append(t)
        self._x.append(x)
        self._buffered += x.shape[0]
        self.appended += x.shape[0]
        while self._buffered >= CHUNK_ROWS:
            self._flush(CHUNK_ROWS)

    def _flush(self, rows: int) -> None:
        t = np.concatenate(self._t)
        x = np.concatenate(self._x)
        head_t, head_x = t[:rows], x[:rows]
        self._t, self._x = ([t[rows:]], [x[rows:]]) if rows < t.shape[0] else ([], [])
        self._buffered = t.shape[0] - rows
        (tb, t_planes), (xb, x_planes) = _shuffle(head_t), _shuffle(head_x)
        fin = head_t[np.isfinite(head_t)]
        t_min, t_max = (float(fin.min()), float(fin.max())) if fin.size else (None, None)
        self._record({"rows": int(rows), "t_bytes": len(tb), "x_bytes": len(xb),
                      "t_planes": t_planes, "x_planes": x_planes,
                      "t_min": t_min, "t_max": t_max}, tb, xb)
        self._f.flush()  # a killed process keeps every whole chunk (recovery reads them)
        self.rows += rows

    def close(self) -> tuple[str, int]:
        """Write what is buffered, make the file final; (sha256, rows)."""
        if self._buffered:
            self._flush(self._buffered)
        self._f.flush()
        os.fsync(self._f.fileno())
        self._f.close()
        os.replace(self._part, self.path)
        return self._sha.hexdigest(), self.rows

    def abort(self) -> None:
        """Drop the unfinished file."""
        try:
            self._f.close()
        finally:
            self._part.unlink(missing_ok=True)


def emg_folder(settings: Settings) -> Path:
    """Where recording files live: `emg_dir` if set, else `emg/` beside a SQLite
    database file, else (PostgreSQL, in-memory SQLite) `emg/` in the data folder."""
    if settings.emg_dir is not None:
        return Path(settings.emg_dir)
    db_file = sqlite_file(settings.database_url)
    base = db_file.parent if db_file is not None else Path(config.DATA_DIR)
    return base / "emg"


def engine_emg_folder(engine: Engine) -> Path:
    """The EMG recordings' folder of the database `engine` is connected to (beside its
    SQLite file, or `emg_dir` of this installation's settings): an export of another
    database file (`exostudy export --db`) reads that database's recordings."""
    url = engine.url.render_as_string(hide_password=False)
    return emg_folder(get_settings().model_copy(update={"database_url": url}))


def recording_path(settings: Settings, recording_id: int) -> Path:
    """The file of recording `recording_id`."""
    return emg_folder(settings) / f"{recording_id}.emgc"


def _open(path: Path) -> BinaryIO:
    """The recording file for reading; one that is missing or unreadable is the store's
    error (a 409 naming it where a route reads it), not an `OSError` (a 500)."""
    try:
        return open(path, "rb")
    except OSError as exc:
        raise EmgStoreError(f"the recording file {path.name} cannot be read: "
                            f"{exc.strerror or exc}") from exc


def _read_exact(f: BinaryIO, n: int) -> bytes:
    data = f.read(n)
    if len(data) != n:
        raise EmgStoreError("the recording file ends in the middle of a chunk")
    return data


def _read_json(f: BinaryIO) -> dict[str, Any] | None:
    raw = f.read(_LEN.size)
    if not raw:
        return None
    if len(raw) != _LEN.size:
        raise EmgStoreError("the recording file ends in the middle of a chunk header")
    (n,) = _LEN.unpack(raw)
    if n > _MAX_HEADER:
        raise EmgStoreError(f"chunk header of {n} bytes: the file is damaged")
    try:
        doc = json.loads(_read_exact(f, n), parse_constant=_no_constant)
    except ValueError as exc:  # not JSON, not UTF-8, NaN or Infinity
        raise EmgStoreError(f"chunk header is not JSON ({exc}): the file is damaged") \
            from exc
    if not isinstance(doc, dict):
        raise EmgStoreError("chunk header is not an object")
    return doc


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number the writer writes")


def read_header(path: Path) -> Header:
    """The channel count, nominal rate and labels of a recording file."""
    with _open(path) as f:
        return _header(f)


def _header(f: BinaryIO) -> Header:
    if f.read(len(MAGIC)) not in (MAGIC, MAGIC_V1):
        raise EmgStoreError("not an ExoStudy EMG recording file")
    doc = _read_json(f)
    if doc is None:
        raise EmgStoreError("recording file has no header")
    n, fs, labels = doc.get("n_channels"), _finite(doc.get("fs")), doc.get("labels")
    if (not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_CHANNELS
            or fs is None or not fs > 0
            or not isinstance(labels, list) or len(labels) != n
            or not all(isinstance(label, str) for label in labels)):
        raise EmgStoreError("recording file's header (channels, rate, labels) is not one "
                            "the writer writes: the file is damaged")
    return Header(n, fs, tuple(labels))


def _stamps(f: BinaryIO, c: _Chunk) -> NDArray[np.float64]:
    """The chunk's timestamps, read from where `f` stands."""
    return _unshuffle(_read_exact(f, c.t_bytes), np.float64, c.rows, c.t_planes)


def _samples(f: BinaryIO, c: _Chunk, head: Header) -> NDArray[np.float32]:
    """The chunk's samples (rows, channels), read from where `f` stands."""
    return _unshuffle(_read_exact(f, c.x_bytes), np.float32, c.rows * head.n_channels,
                      c.x_planes).reshape(c.rows, head.n_channels)


def iter_chunks(path: Path, damage: list[str] | None = None
                ) -> Iterator[tuple[NDArray[np.float64], NDArray[np.float32]]]:
    """(timestamps, samples) of each chunk in order: one chunk in memory at a time.
    `damage`: a file that stops reading back ends the iteration there, the reason
    appended, instead of raising the store's error (for a reader that keeps what came
    before the damage and says where it stopped)."""
    try:
        with _open(path) as f:
            head = _header(f)
            while (doc := _read_json(f)) is not None:
                c = _chunk(doc, head.n_channels)
                yield _stamps(f, c), _samples(f, c, head)
    except EmgStoreError as exc:
        if damage is None:
            raise
        damage.append(str(exc))


def whole_length(path: Path) -> tuple[int, int]:
    """(bytes, rows) of the file's header and the whole chunks that read back: what a
    `.part` a killed writer left can be kept as. EmgStoreError when not even the header
    is whole."""
    with _open(path) as f:
        head = _header(f)
        good, rows = f.tell(), 0
        while True:
            try:
                doc = _read_json(f)
                if doc is None:
                    break
                c = _chunk(doc, head.n_channels)
                # Decoded, not only framed: a chunk kept must read back.
                _stamps(f, c)
                _samples(f, c, head)
            except EmgStoreError:
                break
            good, rows = f.tell(), rows + c.rows
    return good, rows


def read_window(path: Path, start: float = -np.inf, stop: float = np.inf,
                upto_damage: bool = False
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Timestamps and samples (float64 volts) with start <= t < stop. Chunks whose time
    range (chunk header) misses the window are skipped unread, so a window costs its
    own chunks, not the file. Rows whose timestamp is not finite have no place on the
    time axis and are in no window: the recording's quality says how many
    (`non_finite_timestamps`). `upto_damage`: a chunk that does not read back ends the
    read there with what came before it, instead of the store's error (for an analysis
    that says elsewhere where the file is damaged)."""
    ts: list[NDArray[np.float64]] = []
    xs: list[NDArray[np.float32]] = []
    with _open(path) as f:
        head = _header(f)
        while True:
            try:
                if (doc := _read_json(f)) is None:
                    break
                got = _window_chunk(f, _chunk(doc, head.n_channels), head, start, stop)
            except EmgStoreError:
                if not upto_damage:
                    raise
                break
            if got is not None:
                ts.append(got[0])
                xs.append(got[1])
    if not ts:
        return np.zeros(0), np.zeros((0, head.n_channels))
    return np.concatenate(ts), np.concatenate(xs).astype(np.float64)


def _window_chunk(f: BinaryIO, c: _Chunk, head: Header, start: float, stop: float
                  ) -> tuple[NDArray[np.float64], NDArray[np.float32]] | None:
    """One chunk's rows inside [start, stop), or None; a chunk outside is skipped unread."""
    if c.indexed and (c.t_range is None or c.t_range[1] < start or c.t_range[0] >= stop):
        f.seek(c.t_bytes + c.x_bytes, os.SEEK_CUR)  # never backwards: checked
        return None
    t = _stamps(f, c)
    keep = (t >= start) & (t < stop)
    if not keep.any():
        f.seek(c.x_bytes, os.SEEK_CUR)
        return None
    return t[keep], _samples(f, c, head)[keep]


def file_sha256(path: Path) -> str:
    """The sha256 of a file, read in 1 MB pieces."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while piece := f.read(1 << 20):
            h.update(piece)
    return h.hexdigest()
