"""Everything the server and the worker process say to each other: one typed definition
each, pickled over a `multiprocessing` pipe."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from backend.schemas.live import DeviceReport, LoopReport
from backend.worker.device_gate import DeviceGate
from controller.controllers.spec import ControllerSpec
from controller.device.base import DeviceIdentity
from controller.tick_codec import TickBlock, pack, unpack
from controller.tick_record import TickRecord


def _no_controller() -> ControllerSpec:
    return ControllerSpec("none")


@dataclass(frozen=True, slots=True)
class WorkerConfig:
    """What the worker needs to start: which device, which controller."""

    device_kind: str = "sim"
    device_host: str = "127.0.0.1"
    device_port: int = 5555
    device_seed: int = 1
    device_script: str = "paper-evaluation"
    #: UDP device: the file of the link key (the worker reads it; the key is not sent).
    device_key_file: str = ""
    precompression_pct: float = 25.0
    #: In-process simulator only: samples this many times faster than real time.
    device_speed: float = 1.0
    #: In-process simulator only: publish the wearer's EMG on LSL (`emg_amplifier`).
    device_emg_lsl: bool = False
    #: The controller to start with, validated by the server; it crosses the pipe as
    #: this type (the worker validates it once more before building it).
    spec: ControllerSpec = field(default_factory=_no_controller)
    #: The model set used for calibration when the running controller has none.
    models_path: str = ""
    #: Seconds between status reports.
    status_interval: float = 0.25

    @property
    def controller(self) -> str:
        """The name of the controller the worker starts with."""
        return self.spec.name


@dataclass(frozen=True, slots=True, eq=False)
class TickBatch:
    """Ticks in order, from one run, packed as one block (`controller.tick_codec`).

    A block pickles as one buffer; a tuple of records pickled and unpickled one
    dataclass at a time, which was the server's largest cost in a sped-up study."""

    run_token: int
    ticks: TickBlock

    @classmethod
    def from_records(cls, run_token: int, records: Iterable[TickRecord]) -> TickBatch:
        """A batch of these records."""
        return cls(run_token, pack(records))

    def __len__(self) -> int:
        return int(self.ticks.shape[0])

    @property
    def records(self) -> tuple[TickRecord, ...]:
        """The ticks as records, decoded on each access (the server's own path reads
        the block's columns instead)."""
        return tuple(unpack(self.ticks))


@dataclass(frozen=True, slots=True)
class WorkerStatus:
    """The worker's heartbeat. Its loop and device reports are the health endpoint's
    own types (`backend.schemas.live`): the server shows them as they arrive, so each
    field is defined once, on both sides of the process boundary."""

    pid: int
    run_token: int
    device_kind: str
    loop: LoopReport
    device: DeviceReport
    #: The worker's state (`backend.worker.machine.State` value: idle, controlling,
    #: trial; a calibration is a job beside one of these, not a state).
    state: str = ""
    #: The identity the device proved on the link (None before it joined, and for the
    #: in-process simulator): what hardware profiles are bound to.
    identity: DeviceIdentity | None = None


@dataclass(frozen=True, slots=True)
class Wearer:
    """A simulated wearer for the in-process simulator: who (seed), what they do
    (script), how fast (None: the worker's current speed)."""

    seed: int
    script: str
    speed: float | None = None


#: The stored run's `end_reason` for a timed run that reached its sample count with every
#: sample stored (`RunStarted.limit_reached`): what it was started for is complete,
#: whatever happens to the worker before the experimenter closes it.
TIME_LIMIT_REACHED = "its time limit was reached"


@dataclass(frozen=True, slots=True)
class RunStarted:
    """A new run began (at start-up or after a controller change)."""

    run_token: int
    controller: str
    controller_config: dict[str, Any]
    device_kind: str
    pid: int
    #: The in-process simulator's wearer as the run starts, with the speed asked for it
    #: (after a timed run's end the wearer itself idles at real time); None for any
    #: other device. The server takes its record of the simulation from here, so that
    #: it never holds a wearer the worker does not run.
    wearer: Wearer | None = None
    #: The previous run ended by itself at its time limit, after this many samples (the
    #: ones the worker made, whether or not they all reached the server); None when a
    #: command of the server's ended it. The server stores the run as whole
    #: (`TIME_LIMIT_REACHED`) only if it stored exactly this many of its ticks.
    limit_reached: int | None = None


@dataclass(frozen=True, slots=True)
class WorkerError:
    """Something the experimenter should see (a bad configuration, a device failure)."""

    message: str
    fatal: bool = False


@dataclass(frozen=True, slots=True)
class SetController:
    """Switch controller; the worker starts a new run when it takes effect. With
    `max_ticks`, the worker itself returns to "none" (another run) after that many
    device samples, so a timed trial holds exactly that much data however late the
    server gets round to stopping it."""

    spec: ControllerSpec
    max_ticks: int | None = None
    #: Answered by a `CommandResult` with this id (0: nobody waits for the answer).
    request_id: int = 0
    #: The device the spec's encoder layout was measured on (a hardware profile's);
    #: the worker runs the controller only on that device (`device_gate`). None: no
    #: profile, the default layout, any device.
    device: DeviceGate | None = None
    #: Put this simulated wearer on the in-process simulator first, at the same sample:
    #: the run starts with the wearer's first sample (a trial of exactly one script
    #: from its start). None: the wearer on the device goes on.
    wearer: Wearer | None = None

    @property
    def name(self) -> str:
        """The name of the controller asked for."""
        return self.spec.name


@dataclass(frozen=True, slots=True)
class SetSimulation:
    """Put another virtual wearer (seed) or script on the in-process simulated device.

    Handled inside the running worker (the old device is released first, a fresh
    controller of the same configuration follows, a new run starts) so a study that
    changes participants does not pay a process start and the compilers' warm-up."""

    seed: int
    script: str
    #: Samples this many times faster than real time; None keeps the current speed.
    speed: float | None = None
    #: Answered by a `CommandResult` with this id (0: nobody waits for the answer).
    request_id: int = 0
    #: The new wearer's run ends after this many samples (the next run goes on with the
    #: same controller): a recording of exactly that much of the script, however late
    #: the server stops it. None: the run lasts until the next command.
    max_ticks: int | None = None


@dataclass(frozen=True, slots=True)
class StopWorker:
    """Release the device and exit."""

    reason: str = "requested"


@dataclass(frozen=True, slots=True)
class Calibrate:
    """Collect `seconds` of standing still, then compute the E-UMC offsets."""

    seconds: float = 3.0
    max_std_deg: float = 1.0
    request_id: int = 0


@dataclass(frozen=True, slots=True)
class CalibrationResult:
    """Outcome of a `Calibrate` request; on success the offsets are applied to the E-UMC."""

    request_id: int
    ok: bool
    message: str
    offset_left: float = 0.0
    offset_right: float = 0.0
    std_left_deg: float = float("nan")
    std_right_deg: float = float("nan")
    samples: int = 0


@dataclass(frozen=True, slots=True)
class CommandResult:
    """The worker's answer to a `SetController` or `SetSimulation` with a request id.

    Sent after the command took effect (its `RunStarted` goes first, through the same
    ordered pipe, so `run_token` is already known to the server) or was refused
    (`ok` False, `message` says why). The server waits for this answer, not for a
    guessed number of seconds: a slow worker is late, never wrongly reported as silent.
    """

    request_id: int
    ok: bool
    message: str = ""
    #: The run the command started (0 if none).
    run_token: int = 0


@dataclass(frozen=True, slots=True)
class BringupCapture:
    """Hardware bring-up: read `seconds` of raw samples with both solenoids off (encoder
    zero, direction, cam-to-output offset). Only with controller `none`."""

    seconds: float
    request_id: int = 0


@dataclass(frozen=True, slots=True)
class BringupPulse:
    """Hardware bring-up: energise one solenoid for `seconds` (capped by the worker at
    `backend.worker.bringup.PULSE_MAX_S`) on an unloaded device, then release.

    `offsets` and `directions` are the encoder layout used to judge the spring
    deflection (no load: |alpha| at most `max_alpha_deg` on both sides)."""

    side: str
    seconds: float
    offsets: tuple[int, int, int, int]
    directions: tuple[int, int, int, int]
    max_alpha_deg: float
    request_id: int = 0


@dataclass(frozen=True, slots=True)
class BringupWatchdog:
    """Hardware bring-up: energise one solenoid of an unloaded device, then send nothing
    and time the device's command watchdog (see `BringupPulse` for the layout)."""

    side: str
    offsets: tuple[int, int, int, int]
    directions: tuple[int, int, int, int]
    max_alpha_deg: float
    request_id: int = 0


@dataclass(frozen=True, slots=True)
class BringupRelease:
    """Hardware bring-up: energise one solenoid of an unloaded device, then keep
    commanding it with STOP_HEARTBEAT and time, on the device's clock, how long the
    external heartbeat monitor takes to cut the drivers (see `BringupPulse` for the
    layout)."""

    side: str
    offsets: tuple[int, int, int, int]
    directions: tuple[int, int, int, int]
    max_alpha_deg: float
    request_id: int = 0


#: One raw sample seen during a bring-up step: (seconds since the step began, on the
#: worker's monotonic clock, when the sample arrived; device sequence; device time (s);
#: the four counts; the status word).
RawSample = tuple[float, int, float, int, int, int, int, int]


@dataclass(frozen=True, slots=True)
class BringupResult:
    """The worker's answer to a bring-up command: what it saw, and for a pulse or the
    watchdog test what the device reported back. `ok` False means the step was refused
    or failed; `message` says why (the server judges the captured samples itself)."""

    request_id: int
    ok: bool
    message: str
    samples: tuple[RawSample, ...] = ()
    #: Pulse and watchdog: the device reported the solenoid energised.
    solenoid_seen: bool = False
    #: Pulse and watchdog: the device reported the solenoid off again afterwards.
    released_seen: bool = False
    #: Watchdog: seconds from the last command sent to the first sample with
    #: WATCHDOG_RELEASED and the solenoid off (NaN if it never came).
    release_s: float = float("nan")
    #: Watchdog: the same on the device's clock: the released sample's device time minus
    #: the device time at which the last command was sent (the worker's clock mapped onto
    #: the device's through the fastest sample of the step). An upper bound on the
    #: device's delay from the command's arrival, however late the worker read samples.
    release_device_s: float = float("nan")
    #: Seconds (step clock, as in `samples`) of the last command sent (NaN: none).
    last_command_s: float = float("nan")
    #: Hardware release: device time (s) of the first sample with HEARTBEAT_STOPPED and
    #: of the first one after it with DRIVERS_OFF (NaN: never seen).
    heartbeat_stopped_t: float = float("nan")
    drivers_off_t: float = float("nan")
    #: Hardware release: the drivers were enabled again once the heartbeat resumed.
    drivers_back: bool = False
    #: Seconds the step commanded a solenoid on (its share of the duty-cycle budget).
    energised_s: float = 0.0
    #: The device the step ran on, as it proved on the link (None: no link).
    identity: DeviceIdentity | None = None
    #: The step did not start: controller not `none`, or the device showed a load or
    #: fault before a pulse (nothing was energised).
    refused: bool = False


BringupCommand = BringupCapture | BringupPulse | BringupWatchdog | BringupRelease

#: Everything the server sends the worker (`backend.worker.machine` has a handler each).
WorkerCommand = SetController | SetSimulation | Calibrate | StopWorker | BringupCommand

WorkerMessage = (TickBatch | WorkerStatus | RunStarted | WorkerError | CalibrationResult
                 | CommandResult | BringupResult)
