"""What authenticating every packet costs: protocol version 2 (HMAC-SHA256 tag, sessions,
replay window) per packet, and the tag against version 1's CRC-32 over the same bytes,
on the same machine in the same run (a busy machine slows both alike: the ratio and the
share of the 10 ms period are the results).

    .venv/bin/python bench/bench_link_auth.py [--packets 20000]
"""

from __future__ import annotations

import argparse
import sys
import time
import zlib
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from controller.device.auth import new_session, verify
from controller.device.base import SAMPLE_PERIOD_S, Sample, Status
from controller.device.protocol import (
    CommandPacket,
    decode_frame,
    encode_command,
    encode_sample,
)

KEY = bytes(range(32))


def _time(fn: Callable[[int], object], n: int) -> float:
    """Median over 5 rounds of the per-call time in microseconds."""
    rounds = []
    for _ in range(5):
        t0 = time.perf_counter()
        for k in range(n):
            fn(k)
        rounds.append((time.perf_counter() - t0) / n * 1e6)
    return sorted(rounds)[2]


def main(argv: list[str] | None = None) -> int:
    """Time both framings and print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--packets", type=int, default=20_000)
    n = p.parse_args(argv).packets
    dev, host = new_session(), new_session()

    def v2_sample(k: int) -> object:
        s = Sample(seq=k, t=k * SAMPLE_PERIOD_S, counts=(3100, 3105, 12900, 12890),
                   status=Status.LOCKED_LEFT)
        frame = decode_frame(encode_sample(s, KEY, dev, host), KEY)
        return frame.sender == dev  # the host's session check (v3: no window)

    def v2_command(k: int) -> object:
        return decode_frame(encode_command(CommandPacket(k, True, False, k), KEY, host, dev),
                            KEY)

    packet = encode_sample(Sample(seq=1, t=SAMPLE_PERIOD_S, counts=(3100, 3105, 12900, 12890)),
                           KEY, dev, host)
    signed_part = packet[:-32]

    def tag_check(k: int) -> object:
        return verify(KEY, signed_part, packet[-32:])

    def crc_check(k: int) -> object:
        return zlib.crc32(signed_part) == k

    full = _time(v2_sample, n)
    command = _time(v2_command, n)
    hmac_us = _time(tag_check, n)
    crc_us = _time(crc_check, n)
    rows = [
        ("v2 SAMPLE: build, encode, decode, tag, window", f"{full:.2f} us"),
        ("v2 COMMAND: encode, decode, tag", f"{command:.2f} us"),
        ("tag check alone (HMAC-SHA256, 56 bytes)", f"{hmac_us:.2f} us"),
        ("v1 CRC-32 over the same bytes (baseline)", f"{crc_us:.2f} us"),
        ("tag / CRC", f"{hmac_us / crc_us:.1f} x"),
        ("per 10 ms period (one SAMPLE, one COMMAND)", f"{full + command:.1f} us "
         f"= {100 * (full + command) / 10_000:.2f} % of the period"),
    ]
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
