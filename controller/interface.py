"""The controller interface shared by the live worker loop, offline replay and simulation.

A controller turns each device sample into one `TickRecord`. The same object is used
live and offline, so what runs in a study is exactly what replay reproduces.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from controller.device.base import Sample
from controller.tick_record import TickRecord


class Controller(ABC):
    """Maps samples to tick records, deciding the lock command on the way.

    Implementations must never raise out of `step` for a bad sample: they return a
    flagged record with no new lock instead (the live loop must keep running and the
    exoskeleton must stay safe).
    """

    #: Short name used in configuration, the CLI and the database.
    name: str = "abstract"

    @abstractmethod
    def step(self, sample: Sample) -> TickRecord:
        """Process one sample (100 Hz) and return what happened at this tick."""

    @abstractmethod
    def reset(self) -> None:
        """Forget all history (filters, observation window, held locks)."""

    def warm_up(self) -> None:  # noqa: B027 - optional hook, empty by design
        """Do any just-in-time compilation now, before the loop starts, never in a tick."""
