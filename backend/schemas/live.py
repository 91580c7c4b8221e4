"""Messages on the live WebSocket (`/ws/live`), server to browser.

The browser's `frontend/static/live.js` reads exactly these fields; `STREAM_FIELDS`
lists which tick columns are streamed: those the live pages plot or show, plus `seq`
and `t_host` (gaps and latency). The database keeps them all.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, Field

from backend.core.resources import version
from controller.device.base import MAX_SPEED, DeviceIdentity

#: Tick fields sent to consoles, in column order.
STREAM_FIELDS: tuple[str, ...] = (
    "seq",
    "t",
    "t_host",
    "q_left",
    "q_right",
    "omega_left",
    "omega_right",
    "trigger",
    "post_squat",
    "post_stoop_left",
    "post_stoop_right",
    "post_other",
    "s_curr_squat",
    "s_curr_stoop_left",
    "s_curr_stoop_right",
    "action",
    "lock_left",
    "lock_right",
    "locked_left",
    "locked_right",
    "torque_left",
    "torque_right",
    "plausibility",
)


class LiveTicks(BaseModel):
    """All ticks since the previous message, column by column (NaN sent as null)."""

    type: Literal["ticks"] = "ticks"
    msg_seq: int = Field(description="per-connection message counter; a jump means drops")
    sent_at: float = Field(description="server Unix time when the message was queued")
    run_id: int | None
    dropped: int = Field(description="messages dropped for this connection so far")
    columns: dict[str, list[float | int | bool | str | None]]


class EmgChannelFlags(BaseModel):
    """One channel's live quality, as the EMG strip shows it (`backend.emg.live_envelope`)."""

    clipping: bool = Field(description="samples at the channel's rails in the last 0.5 s")
    flat: bool = Field(description="RMS below 0.1 uV in the last 0.5 s (electrode off?)")
    non_finite: int = Field(description="NaN or infinite samples since the stream connected")


class LiveEmg(BaseModel):
    """The causal EMG envelope of a subscribed stream's channels, decimated for display
    (sent as samples arrive, at most 25 messages a second per stream)."""

    type: Literal["emg"] = "emg"
    session_id: int
    subscription_id: int
    recording_id: int | None
    fs: float = Field(description="rate of `values` (Hz): the display rate")
    t: list[float] = Field(description="session (LSL) clock of each value, s")
    t_end: float = Field(description="session clock of the newest raw sample taken, s")
    clock_correction_s: float = Field(description=(
        "liblsl's estimate of this server's clock minus the amplifier's, added to its "
        "stamps (t_end - clock_correction_s is the amplifier's own stamp)"))
    sent_at: float = Field(description="server Unix time when the message was queued")
    labels: list[str] = Field(description="the montage's channel labels, in order")
    values: list[list[float]] = Field(description="per channel: the envelope in volts")
    flags: list[EmgChannelFlags]


def _finite_or_none(v: float | None) -> float | None:
    return v if v is not None and math.isfinite(v) else None


#: A measurement the worker could not make yet (no ticks, no sample): NaN or infinity
#: on the worker's side, null in JSON.
Measured = Annotated[float | None, AfterValidator(_finite_or_none)]


class LoopReport(BaseModel):
    """What the worker measures about its control loop. The worker sends it in every
    status message (`backend.worker.messages.WorkerStatus`) and `WorkerHealth` shows
    it as is: one definition on both sides of the process boundary."""

    controller: str | None = None
    ticks: int = 0
    period_mean_ms: Measured = None
    jitter_p50_ms: Measured = None
    jitter_p99_ms: Measured = None
    jitter_max_ms: Measured = None
    compute_p50_us: Measured = None
    compute_p99_us: Measured = None
    compute_max_us: Measured = None
    overruns: int = 0
    gaps: int = 0
    timeouts: int = Field(default=0, description="reads that waited for a sample in vain")
    dropped_records: int = Field(default=0, description=(
        "ticks the worker dropped because the server did not take them"))


class WorkerHealth(LoopReport):
    """The worker as the server sees it: its last `LoopReport` and the process."""

    alive: bool
    pid: int | None = None
    restarts: int = 0
    exit_code: int | None = None
    exit_reason: str = ""
    errors: list[str] = Field(default_factory=list)


class DeviceReport(BaseModel):
    """The exoskeleton link as the worker reports it (sent in every status message,
    shown as is in `DeviceHealth`)."""

    alive: bool
    last_sample_age_s: Measured = None
    faults: list[str] = Field(default_factory=list)
    implausible_samples: int = Field(default=0, description=(
        "samples of the current run that failed a plausibility check (no lock taken)"))
    link_drops: dict[str, int] = Field(default_factory=dict, description=(
        "packets dropped by the UDP link since the worker started, by reason: host side "
        "(auth, replay, stale, version, ...) and, as the device reports them, device side "
        "(device_auth, device_replay, device_stale)"))


class DeviceHealth(DeviceReport):
    """The exoskeleton link: the worker's `DeviceReport`, the configured kind, and the
    identity the device proved when the host joined it (None before, and without a
    link)."""

    kind: str
    identity: DeviceIdentity | None = None


class DatabaseHealth(BaseModel):
    """The tick writer."""

    ticks_written: int
    write_failures: int
    #: The error of the last write if it failed; "" once a write succeeds again.
    last_error: str = ""
    current_run_id: int | None = None
    #: Ticks received and waiting to be written.
    backlog: int = 0
    #: Ticks lost because the backlog was full while writes failed.
    ticks_dropped: int = 0


class Health(BaseModel):
    """`GET /api/health`: is the live path working?"""

    status: Literal["ok", "degraded"]
    worker: WorkerHealth
    device: DeviceHealth
    database: DatabaseHealth
    clients: int
    #: The running ExoStudy (the package version), so a report names what produced it.
    version: str = Field(default_factory=version)


class LiveStatus(BaseModel):
    """Sent on connect, on every worker change and once a second."""

    type: Literal["status"] = "status"
    health: Health


class ControllerChoice(BaseModel):
    """Which controller the worker should run."""

    name: str = Field(description="controller name, e.g. none, umc, eumc, pec")
    config: dict[str, object] = Field(default_factory=dict)


class CalibrationRequest(BaseModel):
    """Stand still for `seconds`; the wearer moving more than `max_std_deg` fails it."""

    #: At least 1 s: a calibration needs 100 samples (`calibration.MIN_SAMPLES`).
    seconds: float = Field(default=3.0, ge=1.0, le=30.0)
    max_std_deg: float = Field(default=1.0, gt=0.0, le=10.0)


class CalibrationOutcome(BaseModel):
    """The result of a calibration."""

    ok: bool
    message: str
    offset_left_deg: float
    offset_right_deg: float
    std_left_deg: float | None
    std_right_deg: float | None
    samples: int


class SimulationChoice(BaseModel):
    """The virtual participant and what they do."""

    seed: int = Field(ge=0, le=2**31 - 1, description="virtual participant")
    script: str = Field(description="squat-sequence, stoop-sequence, walking, stairs, "
                        "paper-evaluation")
    speed: float | None = Field(default=None, ge=0.1, le=MAX_SPEED, description=(
        "samples this many times faster than real time (in-process simulator only); "
        "default: as before"))
