"""The simulated wearer as the C device's hardware: the record layouts both sides use,
and that the bridge answers with exactly what the simulated exoskeleton shows under the
same commands (the model itself is the oracle)."""

from __future__ import annotations

import io
import math
import re
from pathlib import Path

from controller.device.base import LockCommand, Status
from controller.sim import plant_bridge
from controller.sim.exoskeleton import SimulatedExoskeleton

PLANT_H = Path(__file__).resolve().parents[3] / "firmware" / "ports" / "linux-sim" / "plant.h"


def test_record_sizes_match_the_c_side() -> None:
    text = PLANT_H.read_text()
    defined = dict(re.findall(r"#define (PLANT_\w+) (\S+)", text))
    assert int(defined["PLANT_COMMAND_BYTES"]) == plant_bridge.COMMAND.size == 4
    assert int(defined["PLANT_REPLY_BYTES"]) == plant_bridge.REPLY.size == 92
    assert defined["PLANT_READY"] == f'"{plant_bridge.READY.decode()}"'
    assert int(defined["PLANT_READY_BYTES"]) == len(plant_bridge.READY)


def test_replies_are_what_the_model_shows_under_the_same_commands() -> None:
    locks = [0, 0, 1, 1, 1, 3, 3, 2, 0] * 30
    source = io.BytesIO(b"".join(plant_bridge.COMMAND.pack(b"C", bits, 0) for bits in locks))
    sink = io.BytesIO()
    steps = plant_bridge.run(source, sink, seed=3, script="squat-sequence",
                             precompression_pct=25.0, loop=False)
    assert steps == len(locks)
    out = sink.getvalue()
    assert out.startswith(plant_bridge.READY)
    replies = out[len(plant_bridge.READY):]
    assert len(replies) == len(locks) * plant_bridge.REPLY.size
    model = SimulatedExoskeleton(seed=3, script="squat-sequence", precompression_pct=25.0)
    for k, bits in enumerate(locks):
        expected = model.tick(LockCommand(k, bool(bits & 1), bool(bits & 2)))
        fields = plant_bridge.REPLY.unpack_from(replies, k * plant_bridge.REPLY.size)
        magic, c0, c1, c2, c3, status, progress, lift, n, flags, name = fields
        assert magic == b"PR" and (c0, c1, c2, c3) == expected.counts
        assert status == int(expected.status) & plant_bridge.MECHANISM_BITS
        assert not status & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT)
        truth = expected.truth
        assert truth is not None
        assert name[:n].decode() == truth.activity and lift == truth.lift_index
        assert (math.isnan(progress) and math.isnan(truth.progress)) \
            or progress == truth.progress
        assert flags == (plant_bridge.FINISHED if model.finished else 0)


def test_a_bad_command_record_ends_the_bridge() -> None:
    source = io.BytesIO(plant_bridge.COMMAND.pack(b"X", 0, 0))
    sink = io.BytesIO()
    assert plant_bridge.run(source, sink, 0, "standing", 25.0, False) == 0
    assert sink.getvalue() == plant_bridge.READY
