"""Hypothesis strategies for XDF files: recordings as LabRecorder writes them (any
channel format, samples with and without time stamps, several Samples chunks, clock
offsets with drift, noise and a clock reset), and the same files spoiled: cut short,
bytes overwritten, sizes inflated, chunks inserted, dropped or repeated."""

from __future__ import annotations

import struct
from typing import Any

from hypothesis import strategies as st

from tests.backend.lab.xdf_writer import PACK, XdfStream, chunk, varlen, xdf_chunks

_INT_RANGE = {"int8": 8, "int16": 16, "int32": 32, "int64": 64}
TYPES = ["EEG", "Markers", "MoCap", "ExoskeletonTicks"]


def _values(fmt: str) -> st.SearchStrategy[object]:
    if fmt == "string":
        return st.text(max_size=6)
    if fmt in _INT_RANGE:
        bits = _INT_RANGE[fmt]
        return st.integers(-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    return st.floats(width=32 if fmt == "float32" else 64)


@st.composite
def streams(draw: st.DrawFn, index: int) -> XdfStream:
    """One stream of up to 30 samples."""
    fmt = draw(st.sampled_from([*sorted(PACK), "string"]))
    kind = draw(st.sampled_from(TYPES))
    width = draw(st.integers(1, 4))
    labels = ["seq", *[f"c{i}" for i in range(width - 1)]] if kind == TYPES[-1] else \
        [f"c{i}" for i in range(width)]
    n = draw(st.integers(0, 30))
    srate = draw(st.sampled_from([0.0, 100.0, 512.5]))
    t0 = draw(st.floats(0.0, 1e6))
    step = draw(st.sampled_from([0.01, 0.002]))
    stamps = [t0 + k * step for k in range(n)]
    rows: Any = [[draw(_values(fmt)) for _ in range(width)] for _ in range(n)]
    if kind == TYPES[-1] and fmt in ("double64", "int32", "int64") and draw(st.booleans()):
        for k, row in enumerate(rows):  # a tick stream as ExoStudy sends it
            row[0] = 1000 + k
    stamped = draw(st.none() | st.lists(st.booleans(), min_size=n, max_size=n))
    cuts = sorted(draw(st.lists(st.integers(0, n), max_size=3)))
    sizes = [b - a for a, b in zip([0, *cuts], [*cuts, n], strict=True)]
    offsets: list[tuple[float, float]] = []
    count = draw(st.integers(0, 6))
    if count:
        base = draw(st.floats(-1000.0, 1000.0))
        drift = draw(st.floats(-1e-5, 1e-5))
        noise = draw(st.lists(st.floats(-5e-5, 5e-5), min_size=count, max_size=count))
        # A reset, when there are enough offsets on each side to tell it from noise.
        reset = draw(st.integers(2, count - 2)) if count >= 5 and draw(st.booleans()) \
            else count
        for j in range(count):
            jump = (2000.0, 100.0) if j >= reset else (0.0, 0.0)
            at = t0 + 5.0 * j + jump[0]
            offsets.append((at, base + drift * (at - t0) + noise[j] + jump[1]))
    return XdfStream(f"s{index}", kind, labels, srate, fmt, stamps, rows,
                     clock_offsets=offsets, stamped=stamped, chunks=sizes)


@st.composite
def recordings(draw: st.DrawFn) -> list[XdfStream]:
    """One to three streams."""
    return [draw(streams(i)) for i in range(draw(st.integers(1, 3)))]


_VARLEN = {1: "<B", 4: "<I", 8: "<Q"}


def _varlen_at(data: bytes, at: int) -> tuple[int, int] | None:
    """(value, bytes it takes) of the variable-length integer at `at`, if well-formed."""
    fmt = _VARLEN.get(data[at]) if at < len(data) else None
    if fmt is None or at + 1 + data[at] > len(data):
        return None
    return struct.unpack_from(fmt, data, at + 1)[0], 1 + data[at]


def _with_length(piece: bytes, change: int) -> bytes:
    """The chunk with its length field changed by `change` (modulo 2**64)."""
    found = _varlen_at(piece, 0)
    if found is None:
        return piece
    value, size = found
    return bytes([8]) + struct.pack("<Q", (value + change) % 2**64) + piece[size:]


def _with_count(piece: bytes, count: int) -> bytes:
    """A Samples chunk declaring `count` samples for the same bytes."""
    found = _varlen_at(piece, 0)
    if found is None or piece[found[1]:found[1] + 2] != struct.pack("<H", 3):
        return piece
    body = piece[found[1] + 2:]
    old = _varlen_at(body, 4)
    if old is None:
        return piece
    return chunk(3, body[:4] + varlen(count % 2**64) + body[4 + old[1]:])


@st.composite
def spoiled(draw: st.DrawFn) -> bytes:
    """A recording's bytes after one to three spoiling steps."""
    pieces = xdf_chunks(draw(recordings()))
    for _ in range(draw(st.integers(1, 3))):
        step = draw(st.sampled_from(["count", "count", "length", "insert", "drop", "repeat",
                                     "overwrite", "overwrite", "cut"]))
        k = draw(st.integers(0, len(pieces) - 1)) if pieces else 0
        if step == "count" and pieces:
            samples = [i for i, p in enumerate(pieces) if _with_count(p, 0) != p]
            if samples:
                k = draw(st.sampled_from(samples))
                found = _varlen_at(pieces[k], 0)
                assert found is not None
                n = _varlen_at(pieces[k][found[1] + 2:], 4)
                now = n[0] if n is not None else 0
                count = draw(st.sampled_from([now - 1, now + 1, 2 * now + 1, 50_000_000,
                                              2**32 - 1, 2**63 - 1]))
                pieces[k] = _with_count(pieces[k], count)
        elif step == "length" and pieces:
            change = draw(st.sampled_from([-3, -2, -1, 1, 2, 3, 8, 2**31, -(2**40)]))
            pieces[k] = _with_length(pieces[k], change)
        elif step == "insert":
            tag = draw(st.integers(0, 8))
            body = draw(st.binary(max_size=40))
            pieces.insert(k, chunk(tag, body))
        elif step == "drop" and pieces:
            del pieces[k]
        elif step == "repeat" and pieces:
            pieces.insert(k, pieces[k])
        else:
            data = bytearray(b"".join(pieces))
            if not data:
                continue
            at = draw(st.integers(0, len(data) - 1))
            if step == "overwrite":
                data[at:at + 1] = bytes([draw(st.integers(0, 255))])
            else:
                del data[at:]
            pieces = [bytes(data)]
    return b"XDF:" + b"".join(pieces)
