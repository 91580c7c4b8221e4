"""The simulated exoskeleton as a `Device`, in process, paced at 100 Hz or free-running."""

from __future__ import annotations

import os
import time
from typing import TYPE_CHECKING

from controller.device.base import MAX_SPEED, Device, DeviceError, LockCommand, Sample
from controller.lowlevel.encoders import DEFAULT_LAYOUT, EncoderLayout
from controller.sim.exoskeleton import SimulatedExoskeleton

if TYPE_CHECKING:
    from controller.sim.emg_amplifier import EmgTap


class SimulatedDevice(Device):
    """A `SimulatedExoskeleton` behind the device interface.

    With `realtime`, sample `k` is due at `start + k * dt` on `time.monotonic` (scheduled
    from the start, so the rate never drifts; a late reader gets the waiting samples at
    once). Without it, `read` returns the next sample immediately. A command sent is
    applied at the next tick; `release` de-energises both solenoids.
    """

    kind = "simulated"

    def __init__(
        self,
        seed: int = 0,
        script: str = "paper-evaluation",
        realtime: bool = True,
        loop: bool = True,
        precompression_pct: float = 25.0,
        layout: EncoderLayout = DEFAULT_LAYOUT,
        speed: float = 1.0,
        emg_lsl: bool = False,
        emg_source_id: str | None = None,
    ) -> None:
        if not 0.1 <= speed <= MAX_SPEED:
            raise ValueError(
                f"speed must be within 0.1..{MAX_SPEED:g} times real time, got {speed}")
        #: Samples come `speed` times faster than real time (device time still steps
        #: 10 ms): rehearsals and tests of long protocols in less wall time.
        self.speed = speed
        self.exo = SimulatedExoskeleton(
            seed=seed,
            script=script,
            layout=layout,
            precompression_pct=precompression_pct,
            loop=loop,
        )
        self.realtime = realtime
        #: The wearer's muscles on LSL as an EMG amplifier (`emg_amplifier`), generated
        #: only while a consumer listens; stamped on the clock the ticks are read on,
        #: so a sped-up simulation's EMG lines up with its ticks' host times.
        self.emg: EmgTap | None = None
        if emg_lsl:
            from controller.sim.emg_amplifier import EmgTap

            self.emg = EmgTap(self.exo,
                              source_id=emg_source_id or f"exostudy-simemg-{os.getpid()}",
                              stamping="spread", only_when_consumed=True, shared=True)
        self._command: LockCommand | None = None
        self._start: float | None = None
        self._closed = False

    def open(self) -> None:
        """Start the clock (the first sample is due now)."""
        self._closed = False
        self._start = time.monotonic()
        if self.emg is not None:
            self.emg.start()

    def read(self, timeout: float) -> Sample | None:
        """The next sample, when due; None after `timeout` s or once a non-looping script
        has ended."""
        if self._closed:
            raise DeviceError("simulated device is closed")
        if self._start is None:
            self.open()
        if self.exo.finished:
            if self.realtime and timeout > 0:
                time.sleep(timeout)
            return None
        if self.realtime:
            assert self._start is not None
            due = self._start + self.exo.seq * self.exo.dt / self.speed
            wait = due - time.monotonic()
            if wait > timeout:
                if timeout > 0:
                    time.sleep(timeout)
                return None
            if wait > 0:
                time.sleep(wait)
        command, self._command = self._command, None
        sample = self.exo.tick(command)
        if self.emg is not None:  # stamped when the tick is read, as the tick itself is:
            # stamping at the due instant instead drifts away from the ticks whenever the
            # reader runs behind (a sped-up study), and lifts lose their EMG
            self.emg.emit(sample)
        return sample

    def wear(self, worn: bool) -> None:
        """Put the exoskeleton on the simulated wearer or take it off (the "no
        exoskeleton" baseline: no torque from the next tick on, the springs never lock)."""
        self.exo.worn = bool(worn)

    def resync(self) -> None:
        """Restart the sample clock from the next sample: after a reader paused on
        purpose (a sped-up simulation waiting for its consumer), samples resume at the
        requested rate instead of arriving all at once."""
        if self._start is not None:
            self._start = time.monotonic() - self.exo.seq * self.exo.dt / self.speed

    def set_speed(self, speed: float) -> None:
        """Samples `speed` times faster than real time from the next one on (no burst:
        the clock restarts there). Raises ValueError outside 0.1..MAX_SPEED."""
        if not 0.1 <= speed <= MAX_SPEED:
            raise ValueError(
                f"speed must be within 0.1..{MAX_SPEED:g} times real time, got {speed}")
        self.speed = speed
        self.resync()

    def send(self, command: LockCommand) -> None:
        """Store the command for the next tick."""
        self._command = command

    def release(self) -> None:
        """De-energise both solenoids from the next tick on (a locked side stays locked
        until its deflection returns to zero: there is no commanded unlock)."""
        self._command = LockCommand(seq=-1, lock_left=False, lock_right=False)

    def close(self) -> None:
        """Release and stop producing samples."""
        self.release()
        self._closed = True
        if self.emg is not None:
            self.emg.close()
