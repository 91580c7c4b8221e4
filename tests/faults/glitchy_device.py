"""A device process with faulty encoders, for the fault tests on implausible samples
(tests/faults/test_sample_faults.py) and the live page's (tests/browser/
test_live_plausibility.py): the protocol's reference device serving the simulated
exoskeleton, 5 % of its samples glitched and a 228 rad/s spike every 97th. Its own
module (it imports only what the device needs), so that a device process forked from
the zygote or spawned afresh loads it without the test modules and pytest."""

from __future__ import annotations

import random
from dataclasses import replace
from pathlib import Path

from controller.device.auth import load_key
from controller.device.base import ENCODER_COUNTS, LockCommand, Sample
from controller.lowlevel.encoders import RAD_PER_COUNT

GLITCH_RATE = 0.05
SPIKE_EVERY = 97  # samples between two 228 rad/s spikes
SPIKE_RAD = 2.28  # in one 10 ms sample: 228 rad/s


class GlitchyEncoders:
    """The simulated exoskeleton with faulty encoders: on 5 % of samples one encoder
    (at random) reads a random count, and every 97th sample both hips read 2.28 rad
    further on (both links of a side, so the spring deflection stays plausible)."""

    def __init__(self, seed: int, script: str) -> None:
        from controller.sim.exoskeleton import SimulatedExoskeleton

        self.inner = SimulatedExoskeleton(seed=seed, script=script, loop=True)
        self.dt = self.inner.dt
        self.rng = random.Random(seed)
        self.k = 0

    @property
    def finished(self) -> bool:
        return self.inner.finished

    def warm_up(self) -> None:
        hook = getattr(self.inner, "warm_up", None)
        if callable(hook):
            hook()

    def tick(self, command: LockCommand | None) -> Sample:
        s = self.inner.tick(command)
        self.k += 1
        c = list(s.counts)
        if self.k % SPIKE_EVERY == 0:
            step = round(SPIKE_RAD / RAD_PER_COUNT)
            c = [(c[0] + step) % ENCODER_COUNTS, (c[1] + step) % ENCODER_COUNTS,
                 (c[2] - step) % ENCODER_COUNTS, (c[3] - step) % ENCODER_COUNTS]  # mirrored
        elif self.rng.random() < GLITCH_RATE:
            c[self.rng.randrange(4)] = self.rng.randrange(ENCODER_COUNTS)
        return replace(s, counts=(c[0], c[1], c[2], c[3]))


def serve_glitchy(port: int, key_file: str, seed: int, script: str) -> None:
    """Device process target: the protocol's reference device with faulty encoders."""
    from controller.sim.device_server import serve

    serve(port, seed, script, model=GlitchyEncoders(seed, script),
          key=load_key(Path(key_file)))
