"""What every controller of the paper does at every 100 Hz tick, around its decision.

Counts to angles (low-level controller), calibration offsets, Kalman velocities and the
trigger, the observation window, the decision, the 0.3 s lock hold and the torque
estimate. All of it runs in one compiled call, `controller.tick_kernel.tick`, over the
state a `TickCore` holds; subclasses (`UMC`, `EUMC`, `PEC`) only choose the decision
mode, its rate and its inputs. The batch replay calls the same `tick`, so a replay runs
exactly the code of the live loop. A sample that cannot be trusted (malformed, faulty,
or implausible for a human hip: `controller.plausibility`) yields a flagged tick with no
new lock: `step` never raises.
"""

from __future__ import annotations

import math
import time
from abc import abstractmethod
from typing import Any

from controller.base import Controller
from controller.config import ControllerConfig
from controller.device.base import Sample
from controller.tick import NAN, TickRecord
from controller.tick_kernel import OUT_FIELDS, Q_RANGE, TickCore

__all__ = ["Q_RANGE", "PipelineController"]

_TYPES = TickRecord.field_types()
_INT_COLS = tuple(i for i, n in enumerate(OUT_FIELDS) if _TYPES[n] is int)
_BOOL_COLS = tuple(i for i, n in enumerate(OUT_FIELDS) if _TYPES[n] is bool)


class PipelineController(Controller):
    """The shared per-tick pipeline; subclasses say which decision `_make_core` compiles in."""

    def __init__(self, config: ControllerConfig | None = None) -> None:
        self.config = config or ControllerConfig()
        c = self.config
        self.layout = c.layout
        self.offsets = c.calibration if c.calibration is not None else (0.0, 0.0)
        #: Every piece of per-tick state, in arrays the compiled tick updates.
        self.core = self._make_core()
        # The building blocks whose arrays the tick updates, under their former names.
        self.velocity = self.core.velocity
        self.window = self.core.window
        self.hold = self.core.hold
        self.torque = self.core.torque

    @abstractmethod
    def _make_core(self) -> TickCore:
        """The compiled tick with this controller's decision mode, rate and inputs."""

    @property
    def tick_index(self) -> int:
        """Ticks processed since the last reset, bad ones included."""
        return self.core.tick_index

    def reset(self) -> None:
        """Forget filters, window, held locks and the trigger phase."""
        self.core.reset()

    def warm_up(self) -> None:
        """Compile the tick (or load it from the numba cache) before the loop starts."""
        self.core.warm_up()

    def step(self, sample: Sample) -> TickRecord:
        """One tick; see the module docstring."""
        t0 = time.perf_counter()
        c = sample.counts
        t = sample.t
        status = int(sample.status)
        try:
            c0, c1, c2, c3 = int(c[0]), int(c[1]), int(c[2]), int(c[3])
            row = self.core.step(c0, c1, c2, c3, float(t), status)
        except (OverflowError, TypeError, ValueError):
            # A count that is not a 64-bit integer: out of range, hence a bad sample
            # (recorded as given where it is an integer at all).
            c0, c1, c2, c3 = (x if isinstance(x, int) else -1 for x in c)
            row = self.core.step(-1, -1, -1, -1, float(t), status)
        vals = [x if x == x else NAN for x in row.tolist()]
        for i in _INT_COLS:
            vals[i] = int(vals[i])
        for i in _BOOL_COLS:
            vals[i] = vals[i] != 0.0
        tr = sample.truth
        fields: list[Any] = [sample.seq, t if math.isfinite(t) else NAN, time.time(),
                             c0, c1, c2, c3, *vals, (time.perf_counter() - t0) * 1e6]
        if tr is None:
            fields += ("", -1, NAN)
        else:
            fields += (tr.activity, tr.lift_index, tr.progress)
        return TickRecord(*fields)
