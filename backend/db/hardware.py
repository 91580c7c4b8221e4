"""Hardware profiles: the outcome of a hardware bring-up (docs/hardware-bringup.md).

One row per bring-up: the encoder calibration it measured, which exoskeleton and link
it was measured on (firmware version, a fingerprint of the link key, never the key),
who ran it and when, and each step's verdict. The profile in effect (the latest one
completed with every step passed) is recorded on every session and trial.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, DateTime, Float, ForeignKey, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from backend.db.models import Base, utcnow


class HardwareProfile(Base):
    """One hardware bring-up: a draft while its steps run, then complete."""

    __tablename__ = "hardware_profiles"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    #: draft (steps still running), complete (every step passed), failed (finished
    #: with a step not passed: kept for the record, never in effect)
    status: Mapped[str] = mapped_column(String(16), default="draft")
    #: `sim` (in-process simulator), `udp-sim` (the simulator process) or `udp` (hardware)
    device: Mapped[str] = mapped_column(String(16))
    firmware_version: Mapped[str] = mapped_column(String(200))
    #: First 8 hex digits of SHA-256 of the link key ("" without a key).
    key_id: Mapped[str] = mapped_column(String(16))
    precompression_pct: Mapped[float] = mapped_column(Float)
    #: Counts at zero angle and signs, in sample order (left output, left cam, right
    #: output, right cam): `controller.lowlevel.encoders.EncoderLayout`.
    encoder_offsets: Mapped[list[int]] = mapped_column(JSON)
    encoder_directions: Mapped[list[int]] = mapped_column(JSON)
    #: Cam zero minus output zero (counts), left and right: alpha = 0 while unlocked.
    cam_output_offsets: Mapped[list[int]] = mapped_column(JSON)
    #: step name -> {"passed", "message", "at", "values"}
    steps: Mapped[dict[str, Any]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    completed_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
