"""A deterministic stand-in for `SimulatedExoskeleton`, so the network layer is tested on its own.

Its counts are a function of the step number and it latches LOCKED_* while a side's
solenoid is commanded, which is all the device server and the UDP link need to see.
"""

from __future__ import annotations

from controller.device.base import GroundTruth, LockCommand, Sample, Status


class StubExoskeleton:
    """Satisfies `controller.sim.device_server.ExoskeletonModel`."""

    dt = 0.01

    def __init__(self, steps: int | None = None) -> None:
        self.steps = steps
        self.k = 0
        self.commands: list[LockCommand | None] = []

    @property
    def finished(self) -> bool:
        """True after `steps` ticks (never when `steps` is None)."""
        return self.steps is not None and self.k >= self.steps

    def tick(self, command: LockCommand | None) -> Sample:
        """One 10 ms step: counts ramp with k, locks follow the solenoid command."""
        self.commands.append(command)
        status = Status.NONE
        if command is not None and command.lock_left:
            status |= Status.LOCKED_LEFT
        if command is not None and command.lock_right:
            status |= Status.LOCKED_RIGHT
        k = self.k
        self.k += 1
        return Sample(
            seq=k,
            t=k * self.dt,
            counts=(k % 16384, (k * 3) % 16384, (16383 - k) % 16384, 5000),
            status=status,
            truth=GroundTruth(activity="squat", lift_index=k // 100, progress=(k % 100) / 100),
        )


#: The link key the device-server tests share between host and device.
KEY = bytes(range(32))


def serve_stub(port: int, duration: float, queue: object) -> None:
    """Process target for spawn tests: serve the stub and report the summary on `queue`."""
    from controller.sim.device_server import serve

    stats = serve(port=port, seed=0, script="stub", duration=duration, model=StubExoskeleton(),
                  key=KEY)
    queue.put(stats.summary())  # type: ignore[attr-defined]
