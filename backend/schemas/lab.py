"""Request and response bodies of the lab integration (markers, LSL streams, XDF files),
and the marker message on the live WebSocket (the rows stay in `backend.db.lab`)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from backend.lsl.names import LSL_TEXT_PATTERN
from backend.schemas.fields import UtcDatetime

#: The marker buttons a study starts with; a study can change them.
DEFAULT_MARKER_LABELS: tuple[str, ...] = ("box dropped", "participant paused",
                                          "adverse event", "note")


def _label(v: str) -> str:
    v = v.strip()
    if not v:
        raise ValueError("a marker label cannot be empty")
    return v


class MarkerIn(BaseModel):
    """An event marker from the console; it is stamped with the newest tick's time."""

    label: str = Field(min_length=1, max_length=100)
    note: str = Field(default="", max_length=2000)

    _strip = field_validator("label")(_label)


class MarkerOut(BaseModel):
    """A stored marker. `t` is the tick time (device clock) of the run `run_id`;
    `lsl_time` the same instant on the LSL clock."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    session_id: int
    trial_id: int | None
    run_id: int | None
    t: float | None
    lsl_time: float | None
    label: str
    note: str
    source: str
    stream_id: int | None
    created_at: UtcDatetime


class LiveMarker(BaseModel):
    """`/ws/live`: a marker was stored; consoles draw it at tick time `t` of `run_id`."""

    type: Literal["marker"] = "marker"
    marker: MarkerOut


class MarkerLabels(BaseModel):
    """The marker buttons of a study, in hotkey order (keys 1-9)."""

    labels: list[str] = Field(max_length=9)

    @field_validator("labels")
    @classmethod
    def _labels(cls, v: list[str]) -> list[str]:
        out = []
        for i, label in enumerate(v):
            label = label.strip()
            if not label or len(label) > 100:
                raise ValueError(f"label {i + 1} must have 1 to 100 characters")
            out.append(label)
        if len(set(out)) != len(out):
            raise ValueError("labels must be different from each other")
        return out


class LslStreamOut(BaseModel):
    """An LSL stream visible on the network."""

    name: str
    type: str
    source_id: str
    hostname: str
    channel_count: int
    nominal_srate: float
    own: bool = Field(description="one of this server's own outlets")


class MarkerStreamIn(BaseModel):
    """Subscribe the session to an LSL marker stream, by source id (or name if the
    stream has no source id)."""

    name: str = Field(pattern=LSL_TEXT_PATTERN, max_length=200,
                      description="letters, digits, space and . _ - : @ # + / ( )")
    source_id: str = Field(default="", pattern=LSL_TEXT_PATTERN + "|^$", max_length=200,
                           description="as `name`, or empty")


class MarkerStreamOut(BaseModel):
    """A subscription and whether its inlet is connected now."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    session_id: int
    name: str
    stream_type: str
    source_id: str
    hostname: str
    active: bool
    created_at: UtcDatetime
    connected: bool = False
    error: str = Field(default="", description="why the server closed the subscription")


class XdfStreamSummary(BaseModel):
    """One stream of an attached XDF file, aligned with the session's trials."""

    stream_id: int
    name: str
    type: str
    channel_count: int
    nominal_srate: float
    samples: int
    first_time: float | None
    last_time: float | None
    channels: list[str] = Field(description="the first channel labels (at most the "
                                "server's xdf_summary_channels, each cut to 64 characters)")
    labelled_channels: int = Field(description="how many channels the stream's header labels")
    exostudy: bool = Field(description="the stream is one of ExoStudy's own outlets")
    trial_ids: list[int] = Field(description="trials of the session whose ticks it overlaps")
    offset_ms: float | None = Field(
        default=None, description="ExoStudy's tick stream only: median of the XDF time "
        "minus the stored tick's LSL time, matched by sample number")


class XdfAttachmentOut(BaseModel):
    """An attached XDF file."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    session_id: int
    filename: str
    size_bytes: int
    sha256: str
    streams: list[dict[str, Any]]
    created_at: UtcDatetime
