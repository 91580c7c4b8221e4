"""Messages on the live WebSocket (`/ws/live`), server to browser.

The browser's `frontend/static/live.js` reads exactly these fields; `STREAM_FIELDS`
lists which tick columns are streamed: those the live pages plot or show, plus `seq`
and `t_host` (gaps and latency). The database keeps them all.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

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


class WorkerHealth(BaseModel):
    """The worker as the server sees it."""

    alive: bool
    pid: int | None = None
    restarts: int = 0
    exit_code: int | None = None
    exit_reason: str = ""
    controller: str | None = None
    ticks: int = 0
    period_mean_ms: float | None = None
    jitter_p50_ms: float | None = None
    jitter_p99_ms: float | None = None
    jitter_max_ms: float | None = None
    compute_p99_us: float | None = None
    overruns: int = 0
    gaps: int = 0
    dropped_records: int = 0
    errors: list[str] = Field(default_factory=list)


class DeviceHealth(BaseModel):
    """The exoskeleton link as the worker reports it."""

    alive: bool
    kind: str
    last_sample_age_s: float | None = None
    faults: list[str] = Field(default_factory=list)
    implausible_samples: int = Field(default=0, description=(
        "samples of the current run that failed a plausibility check (no lock taken)"))
    link_drops: dict[str, int] = Field(default_factory=dict, description=(
        "packets dropped by the UDP link since the worker started, by reason: host side "
        "(auth, replay, ...) and, as the device reports them, device side (device_auth, "
        "device_replay)"))


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


class LiveStatus(BaseModel):
    """Sent on connect, on every worker change and once a second."""

    type: Literal["status"] = "status"
    health: Health
