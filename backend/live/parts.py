"""What the app factory attaches to the live path from the layers above it.

The lab's LSL outlets and marker inlets (`backend.lab.hub.Lab`), the EMG inlets
(`backend.emg.live.EmgLab`) and the study's running trials and recordings
(`backend.study.activity`) all sit above the live path: they read what it records. The
runtime starts, stops and feeds them through these three small contracts instead of
importing them, so the packages import in one direction (docs/architecture.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from backend.worker.messages import TickBatch


class LivePart(Protocol):
    """Started and stopped with the live path."""

    def start(self) -> None: ...

    def stop(self) -> None: ...


class TickListener(Protocol):
    """Fed every tick batch, every new run and every calibration, on the supervisor's
    reader thread (it must not block: the lab's outlets push and return)."""

    def on_ticks(self, batch: TickBatch) -> None: ...

    def on_run_started(self, run_token: int, run_id: int) -> None: ...

    def on_calibration(self, ok: bool, message: str) -> None: ...


@dataclass(frozen=True)
class StudyHooks:
    """What the live path asks of the study it serves: what runs now ("trial 3", None
    when nothing does), and closing everything running as interrupted when its worker
    dies (what was closed). A runtime without a study (a test's, a tool's) runs nothing
    and closes nothing."""

    running: Callable[[], str | None] = lambda: None
    interrupt_running: Callable[[str], list[str]] = lambda _reason: []
