"""A small XDF writer for the tests (the format LabRecorder writes: "XDF:" and chunks of
[length-byte count][length][tag][content]); pyxdf's reader checks what it writes."""

from __future__ import annotations

import struct
import uuid
from dataclasses import dataclass, field
from xml.sax.saxutils import escape


def _varlen(n: int) -> bytes:
    if n < 256:
        return bytes([1, n])
    if n < 2**32:
        return bytes([4]) + struct.pack("<I", n)
    return bytes([8]) + struct.pack("<Q", n)


def _chunk(tag: int, content: bytes) -> bytes:
    return _varlen(len(content) + 2) + struct.pack("<H", tag) + content


@dataclass
class XdfStream:
    """One stream: float64 or string samples with their time stamps."""

    name: str
    type: str
    channels: list[str]
    srate: float
    fmt: str  # "double64" or "string"
    stamps: list[float]
    rows: list[list[float]] | list[list[str]]
    source_id: str = ""
    clock_offsets: list[tuple[float, float]] = field(default_factory=list)

    def header(self, sid: int) -> bytes:
        chans = "".join(f"<channel><label>{escape(c)}</label></channel>"
                        for c in self.channels)
        xml = (f'<?xml version="1.0"?><info><name>{escape(self.name)}</name>'
               f"<type>{escape(self.type)}</type>"
               f"<channel_count>{len(self.channels)}</channel_count>"
               f"<nominal_srate>{self.srate}</nominal_srate>"
               f"<channel_format>{self.fmt}</channel_format>"
               f"<source_id>{escape(self.source_id)}</source_id>"
               f"<created_at>0</created_at><desc><channels>{chans}</channels></desc></info>")
        return struct.pack("<I", sid) + xml.encode()

    def samples(self, sid: int) -> bytes:
        out = bytearray(struct.pack("<I", sid))
        out += _varlen(len(self.stamps))
        for ts, row in zip(self.stamps, self.rows, strict=True):
            out += bytes([8]) + struct.pack("<d", ts)
            if self.fmt == "string":
                for v in row:
                    b = str(v).encode()
                    out += _varlen(len(b)) + b
            else:
                out += struct.pack(f"<{len(row)}d", *row)
        return bytes(out)

    def footer(self, sid: int) -> bytes:
        xml = (f'<?xml version="1.0"?><info><first_timestamp>{self.stamps[0]!r}'
               f"</first_timestamp><last_timestamp>{self.stamps[-1]!r}</last_timestamp>"
               f"<sample_count>{len(self.stamps)}</sample_count></info>")
        return struct.pack("<I", sid) + xml.encode()


def write_xdf(streams: list[XdfStream]) -> bytes:
    """The bytes of an XDF file holding `streams` (stream ids 1, 2, ...)."""
    out = bytearray(b"XDF:")
    out += _chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>')
    for sid, s in enumerate(streams, start=1):
        out += _chunk(2, s.header(sid))
    out += _chunk(5, uuid.uuid4().bytes)
    for sid, s in enumerate(streams, start=1):
        out += _chunk(3, s.samples(sid))
        for collected, offset in s.clock_offsets:
            out += _chunk(4, struct.pack("<Idd", sid, collected, offset))
    for sid, s in enumerate(streams, start=1):
        out += _chunk(6, s.footer(sid))
    return bytes(out)
