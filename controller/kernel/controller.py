"""`KernelController`: a controller whose every tick is the compiled kernel's.

It turns a device sample into the kernel's inputs and the kernel's output row into a
`TickRecord`. A controller module (`controller.controllers.umc`,
`controller.controllers.pec`, ...) subclasses it only to build its `Kernel` with its
decision step and data. A sample that cannot be trusted yields a flagged tick with no
new lock: `step` never raises.
"""

from __future__ import annotations

import math
import time
from typing import Any

from controller.config import ControllerConfig
from controller.device.base import Sample
from controller.interface import Controller
from controller.kernel.core import Kernel
from controller.kernel.records import ROW_FIELDS
from controller.tick_record import NAN, TickRecord

_TYPES = TickRecord.field_types()
_INT_COLS = tuple(i for i, n in enumerate(ROW_FIELDS) if _TYPES[n] is int)
_BOOL_COLS = tuple(i for i, n in enumerate(ROW_FIELDS) if _TYPES[n] is bool)


class KernelController(Controller):
    """A controller run by the compiled kernel (`self.kernel`)."""

    def __init__(self, config: ControllerConfig, kernel: Kernel) -> None:
        self.config = config
        #: Every piece of per-tick state, in the records and arrays the tick updates.
        self.kernel = kernel

    @property
    def tick_index(self) -> int:
        """Ticks processed since the last reset, bad ones included."""
        return self.kernel.tick_index

    def reset(self) -> None:
        """Forget filters, window, held locks and the trigger phase."""
        self.kernel.reset()

    def warm_up(self) -> None:
        """Compile the tick (or load it from the numba cache) before the loop starts."""
        self.kernel.warm_up()

    def step(self, sample: Sample) -> TickRecord:
        """One tick; see the module docstring."""
        t0 = time.perf_counter()
        c = sample.counts
        t = sample.t
        status = int(sample.status)
        try:
            c0, c1, c2, c3 = int(c[0]), int(c[1]), int(c[2]), int(c[3])
            self.kernel.step(c0, c1, c2, c3, float(t), status)
        except (OverflowError, TypeError, ValueError):
            # A count that is not a 64-bit integer: out of range, hence a bad sample
            # (recorded as given where it is an integer at all).
            c0, c1, c2, c3 = (x if isinstance(x, int) else -1 for x in c)
            self.kernel.step(-1, -1, -1, -1, float(t), status)
        vals = [x if x == x else NAN for x in self.kernel.values.tolist()]
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
