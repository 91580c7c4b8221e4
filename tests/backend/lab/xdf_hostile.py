"""Hostile XDF files of the reviews (issues 23 and 28), built here byte by byte."""

from __future__ import annotations

import struct

import numpy as np

from backend.lab.lsl_outlets import TICK_CHANNEL_NAMES
from tests.backend.lab.xdf_writer import BOUNDARY, XdfStream, chunk, header_xml, write_xdf

_FILE_HEADER = chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>')


def _stream_header(sid: int, xml: bytes) -> bytes:
    return chunk(2, struct.pack("<I", sid) + xml)


def declaring(samples: int, channels: int = 1, fmt: str = "string") -> bytes:
    """A tiny file whose one Samples chunk declares `samples` samples and holds one."""
    one = bytes([8]) + struct.pack("<d", 1.0) + (
        (bytes([1, 1]) + b"x") * channels if fmt == "string" else bytes(8 * channels))
    body = struct.pack("<I", 1) + bytes([4]) + struct.pack("<I", samples) + one
    return b"XDF:" + _FILE_HEADER + _stream_header(
        1, header_xml("crafted", "EEG", channels, 100, fmt)) + chunk(3, body)


def past_its_end() -> bytes:
    """Issue 28's file: a Samples chunk declaring 1 string sample in 3 bytes (a check of
    the least size passes), whose sample is stamped, so a reader that reads on from the
    file takes its time stamp from the next 8 bytes: the 2 left in the chunk, the next
    Boundary chunk's length field, tag and 2 bytes of content. The content's next 2
    bytes then read as an empty string, and what follows as a stream header and a
    Samples chunk declaring 50,000,000 string samples, which that reader allocates."""
    hidden = (_stream_header(2, b"<info><name>h</name><channel_count>1</channel_count>"
                                b"<nominal_srate>0</nominal_srate><channel_format>string"
                                b"</channel_format></info>")
              + chunk(3, struct.pack("<I", 2) + bytes([4]) + struct.pack("<I", 50_000_000)))
    boundary = bytes([0, 0, 1, 0]) + hidden
    assert len(boundary) + 2 < 256  # a 1-byte length field, as the misreading needs
    samples = struct.pack("<I", 1) + bytes([1, 1]) + bytes([8, 0, 0])
    return (b"XDF:" + _FILE_HEADER
            + _stream_header(1, header_xml("Markers", "Markers", 1, 0, "string", ["m"]))
            + chunk(3, samples) + chunk(5, boundary))


def small_stream(name: str = "EMG", n: int = 50) -> XdfStream:
    """A plain stream of `n` double samples at 100 Hz from t = 100 s."""
    return XdfStream(name, "EMG", ["a", "b"], 100.0, "double64",
                     [100.0 + i / 100 for i in range(n)], [[float(i), -float(i)]
                                                           for i in range(n)])


def clock_offsets(count: int, seed: int = 4) -> bytes:
    """A small stream followed by `count` ClockOffset chunks of random times and values
    (issue 28: 20,000 of them in 481 kB took 465 s of a core)."""
    rng = np.random.default_rng(seed)
    base = write_xdf([small_stream()])
    times = rng.uniform(0.0, 1000.0, count)
    values = rng.uniform(-100.0, 100.0, count)
    return base + b"".join(chunk(4, struct.pack("<Idd", 1, t, v))
                           for t, v in zip(times.tolist(), values.tolist(), strict=True))


def string_stream(samples: int) -> bytes:
    """One string stream of `samples` stamped two-letter samples in a single chunk
    (13 bytes a sample: 1.4 million make issue 28's 18 MB file; two letters, because
    Python shares one object among all equal one-letter strings)."""
    rec = np.zeros(samples, dtype=[("f", "u1"), ("t", "<f8"), ("w", "u1"), ("n", "u1"),
                                   ("c", "S2")])
    rec["f"], rec["t"], rec["w"], rec["n"], rec["c"] = 8, 100.0 + np.arange(samples) / 1e3, \
        1, 2, b"ab"
    body = struct.pack("<I", 1) + bytes([4]) + struct.pack("<I", samples) + rec.tobytes()
    return b"XDF:" + _FILE_HEADER + _stream_header(
        1, header_xml("Words", "Markers", 1, 1000, "string", ["w"])) + chunk(3, body)


def boundary_flood(count: int) -> bytes:
    """A small stream and `count` Boundary chunks (2 million of them in 40 MB)."""
    return write_xdf([small_stream()]) + chunk(5, BOUNDARY) * count


def tick_stream(n: int = 20, *, fmt: str = "double64", labels: list[str] | None = None,
                channels: int | None = None, srate: str = "100", seq: list[float] | None = None,
                stamps: list[float] | None = None) -> bytes:
    """A file holding an ExskeletonTicks-typed stream whose fields can each be spoiled:
    its format, labels, declared channel count, nominal rate, seq values, time stamps."""
    labels = list(TICK_CHANNEL_NAMES) if labels is None else labels
    count = len(labels) if channels is None else channels
    seq = [1000.0 + i for i in range(n)] if seq is None else seq
    stamps = [50.0 + i / 100 for i in range(n)] if stamps is None else stamps
    rows: list[list[float]] | list[list[str]]
    if fmt == "string":
        rows = [[str(q)] + ["0"] * (count - 1) for q in seq]
    else:
        rows = [[q] + [0.0] * (count - 1) for q in seq]
    s = XdfStream("ExoStudy", "ExoskeletonTicks", labels, 100.0, fmt, stamps, rows)
    body = chunk(3, s.samples(1))
    xml = header_xml("ExoStudy", "ExoskeletonTicks", count, srate, fmt, labels)
    return b"XDF:" + _FILE_HEADER + _stream_header(1, xml) + body


def label_flood(streams: int, channels: int, label: str = "channel-label-{}") -> bytes:
    """Issue 28's label flood, scaled down: `streams` headers that each declare and label
    `channels` int8 channels and hold no samples, then one small stream with samples
    (the review's 63 MB file: 96 headers of 65,536 channels; its summary took 25 MB
    stored and 19 MB a GET, and the server 400 MB more while reading it)."""
    labels = [label.format(c) for c in range(channels)]
    # The small stream is stream 1; the flood's are 100 on.
    headers = b"".join(_stream_header(sid, header_xml(f"flood {sid}", "EEG", channels, 0,
                                                      "int8", labels))
                       for sid in range(100, 100 + streams))
    return write_xdf([small_stream()]) + headers


def offset_overflow(seq0: float = 1000.0, n: int = 20) -> bytes:
    """Issue 28: a tick stream stamped 1.7e308 whose seq values match stored ticks; the
    clock difference (about 1.7e308 s) times 1000 was stored as offset_ms Infinity."""
    return tick_stream(n, seq=[seq0 + i for i in range(n)], stamps=[1.7e308] * n)
