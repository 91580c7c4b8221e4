"""The device interface and the data it exchanges with the worker.

`Sample` and `LockCommand` are the only types that cross the device boundary: the
in-process simulator, the UDP device and a real exoskeleton's firmware all speak them.
"""

from __future__ import annotations

import enum
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Self

ENCODER_BITS = 14
ENCODER_COUNTS = 1 << ENCODER_BITS  # 16384 counts per turn, 0.0219 deg per count

#: The sample period, s: the device reads its encoders every 10 ms and the controller
#: runs one tick per sample (docs/hardware.md). Every period, rate and default time
#: step in the project derives from this one value.
SAMPLE_PERIOD_S = 0.01
#: The same rate in samples per second (100 Hz), derived so that the two cannot disagree.
SAMPLE_RATE_HZ = 1.0 / SAMPLE_PERIOD_S

#: The fastest a simulated device may be asked to run: 400 times real time, 40,000
#: samples/s requested. That is above what one core makes of the simulator and the
#: control loop (about 10,000-20,000 ticks/s here), so at this setting a sped-up
#: simulation runs as fast as the worker and the server's recorder allow (the worker
#: holds it while ticks queue); the bound only keeps a typo from asking for 10^6.
MAX_SPEED = 400.0


class Status(enum.IntFlag):
    """Status bits a device reports with each sample (same bit values on the wire)."""

    NONE = 0
    SOLENOID_LEFT = 1 << 0
    SOLENOID_RIGHT = 1 << 1
    LOCKED_LEFT = 1 << 2
    LOCKED_RIGHT = 1 << 3
    HARD_STOP_LEFT = 1 << 4
    HARD_STOP_RIGHT = 1 << 5
    ENCODER_FAULT = 1 << 6
    WATCHDOG_RELEASED = 1 << 7
    SUPPLY_FAULT = 1 << 8
    #: The firmware stopped toggling its heartbeat output because the latest applied
    #: command asked it to (the bring-up probe of the hardware release).
    HEARTBEAT_STOPPED = 1 << 9
    #: The board reads its solenoid drivers' enable as off: the hardware heartbeat
    #: monitor cut them, and no firmware output can energise a solenoid.
    DRIVERS_OFF = 1 << 10

    @property
    def is_fault(self) -> bool:
        """Faults make a sample unusable for control; locks and hard stops are states."""
        return bool(self & (Status.ENCODER_FAULT | Status.SUPPLY_FAULT))


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """What a simulated wearer was really doing; absent for real hardware."""

    activity: str
    lift_index: int = -1
    progress: float = float("nan")


@dataclass(frozen=True, slots=True)
class Sample:
    """One reading of the exoskeleton's four absolute encoders.

    Counts are raw 14-bit values in the order left output link, left cam link, right
    output link, right cam link. Hip flexion comes from the output links; the spring
    deflection from output minus cam (see `controller.lowlevel.encoders`).
    """

    seq: int
    t: float
    counts: tuple[int, int, int, int]
    status: Status = Status.NONE
    truth: GroundTruth | None = None

    def __post_init__(self) -> None:
        if len(self.counts) != 4:
            raise ValueError(f"a sample needs 4 encoder counts, got {len(self.counts)}")


@dataclass(frozen=True, slots=True)
class LockCommand:
    """Energise the solenoid of each side (True) or not. There is no commanded unlock:
    a side releases by itself when its spring deflection returns to zero.

    `stop_heartbeat` is the bring-up probe of the hardware release: the firmware stops
    toggling its heartbeat output while the latest applied command carries it, so that
    the external monitor must cut the drivers. It never energises anything itself."""

    seq: int
    lock_left: bool
    lock_right: bool
    stop_heartbeat: bool = False


NO_LOCK = LockCommand(seq=-1, lock_left=False, lock_right=False)


@dataclass(frozen=True, slots=True)
class DeviceIdentity:
    """Which device is on the link, as it proved with its CHALLENGE: what hardware
    profiles are bound to. `unique_id` is 32 lowercase hex digits (the processor's id or
    a simulator's configured one), `firmware` its name and version, `key_id` names the
    link key (16 hex digits, `controller.device.auth.key_id`), `device_session` the
    device's boot session."""

    unique_id: str
    firmware: str
    key_id: str
    device_session: int


class DeviceError(RuntimeError):
    """The device cannot deliver samples or accept commands (link down, fault)."""


class Device(ABC):
    """An exoskeleton: a stream of samples at the device's own rate and a command input.

    Implementations: `SimulatedDevice` (in process), `UdpDevice` (the wire protocol in
    `docs/device-protocol.md`). The worker loop is the only caller.
    """

    kind: str = "abstract"

    @abstractmethod
    def open(self) -> None:
        """Connect. Called once, in the process that will use the device."""

    @abstractmethod
    def read(self, timeout: float) -> Sample | None:
        """Block until the next sample or `timeout` seconds; None on timeout."""

    @abstractmethod
    def send(self, command: LockCommand) -> None:
        """Send a lock command. Must not block."""

    @abstractmethod
    def release(self) -> None:
        """Make the device safe: stop energising the solenoids. Must never raise."""

    @abstractmethod
    def close(self) -> None:
        """Release and disconnect."""

    def faults(self) -> list[str]:
        """Human-readable faults seen since the last call (link loss, late packets, ...)."""
        return []

    @property
    def identity(self) -> DeviceIdentity | None:
        """The device's identity once the link has proved it; None without a link."""
        return None

    def link_counters(self) -> dict[str, int]:
        """Packets dropped since `open()`, by reason (authentication, replay, ...), as the
        host and, where it reports them, the device counted them; empty without a link."""
        return {}

    def __enter__(self) -> Self:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
