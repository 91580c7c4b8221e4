"""Hardware profiles: the outcome of a hardware bring-up (docs/hardware-bringup.md).

One row per bring-up: the encoder calibration it measured, which exoskeleton and link
it was measured on (the identity the device proved in its CHALLENGE: unique id and
firmware, and the key id, never the key), who ran it and when, and each step's verdict.
The profile in effect (the latest one completed with every step passed) is recorded on
every session and trial, and applied only to the device it was made on.

A device grant is the lab's permission for one account to use the exoskeleton (pulse a
solenoid, start a controller or a trial, run the bring-up): given and revoked by an
administrator, never implied by a study role (docs/access.md).
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
    #: with a step not passed: kept for the record, never in effect), expired (a draft
    #: closed unfinished: past its lifetime, or another device came on the link)
    status: Mapped[str] = mapped_column(String(16), default="draft")
    #: `sim` (in-process simulator), `udp-sim` (the simulator process) or `udp` (hardware)
    device: Mapped[str] = mapped_column(String(16))
    firmware_version: Mapped[str] = mapped_column(String(200))
    #: The link key's id (16 hex digits, `controller.device.auth.key_id`; "" without a
    #: link; 8 hex digits of SHA-256 of the key in profiles made before protocol 3).
    key_id: Mapped[str] = mapped_column(String(16))
    #: The unique id the device reported in its CHALLENGE (32 hex digits; "" for the
    #: in-process simulator, and in profiles made before protocol 3, which therefore
    #: match no device).
    unique_id: Mapped[str] = mapped_column(String(32), default="", server_default="")
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
    #: A draft is closed as `expired` at this time (docs/hardware-bringup.md).
    expires_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))


class DeviceGrant(Base):
    """An account's right to use the exoskeleton, given by an administrator. One row per
    account holding it; revoking deletes the row (the audit log keeps the history)."""

    __tablename__ = "device_grants"

    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"),
                                         primary_key=True)
    granted_by: Mapped[int | None] = mapped_column(ForeignKey("users.id",
                                                              ondelete="SET NULL"))
    granted_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
