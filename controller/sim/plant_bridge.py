"""The simulated wearer and mechanism as the hardware of the C device (firmware/ports/linux-sim).

The C device (`firmware/build/exostudy-device`) runs the portable firmware core against
the same `SimulatedExoskeleton` the Python device server uses: it starts this module as
its child and, once per sample period, writes the solenoid command it drives and reads
back what the mechanism and the encoders then show. One fixed binary record each way,
over the child's standard input and output, so that no parsing can go wrong and a
period costs one pipe round trip:

- at start, after the one-time costs (numba loading compiled code), this side writes
  `READY` (8 bytes) so the device binds its port only once a period is cheap;
- C -> Python, `COMMAND` (4 bytes): magic `b"C"`, lock bits (bit 0 left, bit 1 right),
  two reserved zero bytes;
- Python -> C, `REPLY` (92 bytes, little-endian): magic `b"PR"`, the four raw counts
  (u16, protocol order), the mechanism's status bits (u32: LOCKED_*, HARD_STOP_*,
  SUPPLY_FAULT; the device sets the solenoid bits itself), ground truth (f64 progress,
  i32 lift index, u8 activity length), u8 flags (bit 0: the script has ended) and the
  activity name padded to 64 bytes.

The layouts are mirrored in firmware/ports/linux-sim/plant.h. End of input (the device
exited) ends this process; so does the death of the device (PR_SET_PDEATHSIG, asked for
by the device before it starts this interpreter).
"""

from __future__ import annotations

import argparse
import math
import struct
import sys
from collections.abc import Sequence
from typing import BinaryIO

from controller.device.base import LockCommand, Status

READY = b"EXOPLNT1"
COMMAND = struct.Struct("<cBH")
REPLY = struct.Struct("<2s4HIdiBB64s")
FINISHED = 0x01
#: What the mechanism and supply report; the device owns the solenoid, encoder-fault
#: and watchdog bits.
MECHANISM_BITS = int(Status.LOCKED_LEFT | Status.LOCKED_RIGHT | Status.HARD_STOP_LEFT
                     | Status.HARD_STOP_RIGHT | Status.SUPPLY_FAULT)


def reply_for(model_sample_counts: tuple[int, int, int, int], status: int, progress: float,
              lift: int, activity: str, finished: bool) -> bytes:
    """One REPLY record (exposed for tests)."""
    name = activity.encode("utf-8")[:64]
    return REPLY.pack(b"PR", *model_sample_counts, status & MECHANISM_BITS,
                      progress, lift, len(name), FINISHED if finished else 0, name)


def run(source: BinaryIO, sink: BinaryIO, seed: int, script: str, precompression_pct: float,
        loop: bool) -> int:
    """Answer COMMAND records with REPLY records until `source` ends; returns the number
    of periods stepped."""
    from controller.sim.exoskeleton import SimulatedExoskeleton

    model = SimulatedExoskeleton(seed=seed, script=script,
                                 precompression_pct=precompression_pct, loop=loop)
    # One throwaway step on a second model pays numba's loading before READY.
    SimulatedExoskeleton(seed=seed, script=script, precompression_pct=precompression_pct,
                         loop=False).tick(None)
    sink.write(READY)
    sink.flush()
    steps = 0
    seq = 0
    while True:
        record = source.read(COMMAND.size)
        if len(record) < COMMAND.size:
            return steps
        magic, locks, reserved = COMMAND.unpack(record)
        if magic != b"C" or reserved or locks & ~3:
            print(f"plant-bridge: bad command record {record.hex()}", file=sys.stderr)
            return steps
        sample = model.tick(LockCommand(seq, bool(locks & 1), bool(locks & 2)))
        seq += 1
        truth = sample.truth
        progress = truth.progress if truth is not None else math.nan
        lift = truth.lift_index if truth is not None else -1
        activity = truth.activity if truth is not None else ""
        sink.write(reply_for(sample.counts, int(sample.status), progress, lift, activity,
                             bool(model.finished)))
        sink.flush()
        steps += 1


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m controller.sim.plant_bridge --seed S --script NAME [--loop]`."""
    parser = argparse.ArgumentParser(prog="plant-bridge", description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--script", default="paper-evaluation")
    parser.add_argument("--precompression", type=float, default=25.0)
    parser.add_argument("--loop", action="store_true")
    args = parser.parse_args(argv)
    try:
        run(sys.stdin.buffer, sys.stdout.buffer, args.seed, args.script, args.precompression,
            args.loop)
    except ValueError as exc:  # an unknown script: the device shows this message
        print(f"plant-bridge: {exc}", file=sys.stderr)
        return 2
    except (BrokenPipeError, KeyboardInterrupt):
        return 0
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
