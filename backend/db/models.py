"""ORM models. The tick table's columns come from `controller.tick.TickRecord`, the one
definition of a tick, so the stored row and the worker's record cannot drift apart
(a test checks the migrations build the same schema)."""

from __future__ import annotations

import dataclasses
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    BigInteger,
    Boolean,
    Column,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    String,
    Table,
    Text,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column
from sqlalchemy.types import TypeEngine

from controller.tick import TickRecord


def utcnow() -> datetime:
    """Timezone-aware now; stored as UTC."""
    return datetime.now(UTC)


class Base(DeclarativeBase):
    """Declarative base of every table."""


class Run(Base):
    """One continuous stream of ticks: one worker lifetime with one controller setting.

    A restart of the worker, or a change of controller, starts a new run, so every tick
    can be traced to the exact configuration that produced it.
    """

    __tablename__ = "runs"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    started_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    ended_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    device_kind: Mapped[str] = mapped_column(String(32))
    controller: Mapped[str] = mapped_column(String(32))
    config_json: Mapped[str] = mapped_column(Text, default="{}")
    worker_pid: Mapped[int | None] = mapped_column(Integer)
    end_reason: Mapped[str | None] = mapped_column(String(200))
    tick_count: Mapped[int] = mapped_column(BigInteger, default=0)


def _sql_type(tp: object) -> TypeEngine[Any]:
    mapping: dict[object, TypeEngine[Any]] = {
        "int": BigInteger(),
        "float": Float(),
        "bool": Boolean(),
        "str": String(32),
    }
    return mapping[tp]


def tick_columns() -> list[Column[Any]]:
    """The tick table's data columns, in `TickRecord` order."""
    cols: list[Column[Any]] = []
    for f in dataclasses.fields(TickRecord):
        cols.append(Column(f.name, _sql_type(f.type), nullable=True))
    return cols


ticks_table = Table(
    "ticks",
    Base.metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("run_id", Integer, ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
    *tick_columns(),
    Index("ix_ticks_run_t", "run_id", "t"),
)

TICK_DATA_COLUMNS: tuple[str, ...] = TickRecord.field_names()
