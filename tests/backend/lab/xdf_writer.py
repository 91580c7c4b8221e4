"""A small XDF writer for the tests (the format LabRecorder writes: "XDF:" and chunks of
[length-byte count][length][tag][content]); pyxdf's reader checks what it writes, and
the hostile files of the XDF tests are built from its pieces."""

from __future__ import annotations

import struct
import uuid
from dataclasses import dataclass, field
from xml.sax.saxutils import escape

#: struct codes of the numeric channel formats.
PACK = {"double64": "d", "float32": "f", "int64": "q", "int32": "i", "int16": "h",
        "int8": "b"}
#: The 16 bytes of a Boundary chunk (a fixed UUID in LabRecorder's files; any here).
BOUNDARY = uuid.UUID("43a5a6dc-cbf5-410f-b30e-d5467383cbe4").bytes


def varlen(n: int) -> bytes:
    """A variable-length integer in its shortest form."""
    if n < 256:
        return bytes([1, n])
    if n < 2**32:
        return bytes([4]) + struct.pack("<I", n)
    return bytes([8]) + struct.pack("<Q", n)


def chunk(tag: int, content: bytes) -> bytes:
    """One chunk: its length (tag included), tag and content."""
    return varlen(len(content) + 2) + struct.pack("<H", tag) + content


def header_xml(name: str, type_: str, channels: int | str, srate: float | str, fmt: str,
               labels: list[str] | None = None, source_id: str = "",
               units: list[str] | None = None) -> bytes:
    """A stream header's XML (the labels, and units when given, under desc/channels)."""
    unit = units or [""] * len(labels or [])
    chans = "" if labels is None else "<desc><channels>" + "".join(
        f"<channel><label>{escape(c)}</label>"
        + (f"<unit>{escape(u)}</unit>" if u else "") + "</channel>"
        for c, u in zip(labels, unit, strict=True)) + "</channels></desc>"
    return (f'<?xml version="1.0"?><info><name>{escape(name)}</name>'
            f"<type>{escape(type_)}</type>"
            f"<channel_count>{channels}</channel_count>"
            f"<nominal_srate>{srate}</nominal_srate>"
            f"<channel_format>{fmt}</channel_format>"
            f"<source_id>{escape(source_id)}</source_id>"
            f"<created_at>0</created_at>{chans}</info>").encode()


@dataclass
class XdfStream:
    """One stream: numeric or string samples with their time stamps.

    `stamped[k]` False writes sample k without its time stamp (the reader then puts it
    one nominal interval after the previous one); `chunks` splits the samples into
    Samples chunks of those sizes (default: one chunk)."""

    name: str
    type: str
    channels: list[str]
    srate: float
    fmt: str  # "double64", "float32", "int64", "int32", "int16", "int8" or "string"
    stamps: list[float]
    rows: list[list[float]] | list[list[str]] | list[list[int]]
    source_id: str = ""
    clock_offsets: list[tuple[float, float]] = field(default_factory=list)
    stamped: list[bool] | None = None
    chunks: list[int] | None = None
    units: list[str] | None = None

    def header(self, sid: int) -> bytes:
        return struct.pack("<I", sid) + header_xml(
            self.name, self.type, len(self.channels), self.srate, self.fmt,
            self.channels, self.source_id, self.units)

    def sample(self, k: int) -> bytes:
        out = bytearray()
        if self.stamped is None or self.stamped[k]:
            out += bytes([8]) + struct.pack("<d", self.stamps[k])
        else:
            out += bytes([0])
        row = self.rows[k]
        if self.fmt == "string":
            for v in row:
                b = str(v).encode()
                out += varlen(len(b)) + b
        else:
            out += struct.pack(f"<{len(row)}{PACK[self.fmt]}", *row)
        return bytes(out)

    def sample_chunks(self, sid: int) -> list[bytes]:
        sizes = self.chunks if self.chunks is not None else [len(self.stamps)]
        out, k = [], 0
        for size in sizes:
            body = bytearray(struct.pack("<I", sid)) + varlen(size)
            for i in range(k, k + size):
                body += self.sample(i)
            out.append(bytes(body))
            k += size
        return out

    def samples(self, sid: int) -> bytes:
        """The content of a single Samples chunk holding every sample."""
        return struct.pack("<I", sid) + varlen(len(self.stamps)) + b"".join(
            self.sample(k) for k in range(len(self.stamps)))

    def footer(self, sid: int) -> bytes:
        first = self.stamps[0] if self.stamps else 0.0
        last = self.stamps[-1] if self.stamps else 0.0
        xml = (f'<?xml version="1.0"?><info><first_timestamp>{first!r}'
               f"</first_timestamp><last_timestamp>{last!r}</last_timestamp>"
               f"<sample_count>{len(self.stamps)}</sample_count></info>")
        return struct.pack("<I", sid) + xml.encode()


def xdf_chunks(streams: list[XdfStream]) -> list[bytes]:
    """The chunks of an XDF file holding `streams` (stream ids 1, 2, ...), in
    LabRecorder's order: file header, stream headers, a boundary, samples and clock
    offsets, stream footers."""
    out = [chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>')]
    out += [chunk(2, s.header(sid)) for sid, s in enumerate(streams, start=1)]
    out.append(chunk(5, BOUNDARY))
    for sid, s in enumerate(streams, start=1):
        out += [chunk(3, body) for body in s.sample_chunks(sid)]
        out += [chunk(4, struct.pack("<Idd", sid, collected, offset))
                for collected, offset in s.clock_offsets]
    out += [chunk(6, s.footer(sid)) for sid, s in enumerate(streams, start=1)]
    return out


def write_xdf(streams: list[XdfStream]) -> bytes:
    """The bytes of an XDF file holding `streams` (stream ids 1, 2, ...)."""
    return b"XDF:" + b"".join(xdf_chunks(streams))
