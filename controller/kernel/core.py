"""`Kernel`: one controller's tick state in typed records, and the compiled tick over it.

Built once per controller from its configuration, its compiled entry points (`Compiled`:
the shared tick with the controller's decision step fixed) and its own data. `step`
runs one live tick; the batch replay (`controller.runner.replay`) runs `batch` over the same
state, so live and replay share the code and the state layout.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numba import typeof
from numba.core.registry import CPUDispatcher

from controller.config import ControllerConfig
from controller.intent.kalman import HipVelocityFilter
from controller.intent.onset import ObservationWindow
from controller.kernel.records import (
    ROW,
    FloatArray,
    RecordArray,
    TickState,
    blank_row,
    new_phase,
    new_reference,
    reset_phase,
    settings_record,
)
from controller.lowlevel.actuator import TorqueModel
from controller.lowlevel.lock_hold import LockHold


@dataclass(frozen=True)
class Compiled:
    """A controller's two compiled entry points, each `begin`, its decision and
    `finish`, built by `controller.kernel.entry_points.entry_points(decide)`:

    - `step(state, data, c0, c1, c2, c3, t, status, rows)`: one live tick into `rows[0]`;
    - `batch(state, data, plant, plant_constants, layout, t, q, rows, counts, statuses)`:
      the batch replay, one row per sample.
    """

    step: Callable[..., None]
    batch: Callable[..., None]

    def __post_init__(self) -> None:
        for name in ("step", "batch"):
            if not isinstance(getattr(self, name), CPUDispatcher):
                raise TypeError(f"Compiled.{name} must be compiled with numba's @njit, got "
                                f"{getattr(self, name)!r}")


def _copy(x: Any) -> Any:
    """A deep copy of an array or a named tuple of arrays (for a scratch compile)."""
    if isinstance(x, np.ndarray):
        return x.copy()
    if isinstance(x, tuple):
        return type(x)(*(_copy(a) for a in x))
    return x


def _arrays(x: Any) -> list[np.ndarray]:
    """The arrays in `x`, a record array as one array per field."""
    if isinstance(x, np.ndarray):
        return [x[n] for n in x.dtype.names] if x.dtype.names else [x]
    if isinstance(x, tuple):
        return [a for v in x for a in _arrays(v)]
    return []


class Kernel:
    """All per-tick state of one controller, and its compiled tick.

    `compiled` holds the controller's entry points, `divider` the ticks between two
    decisions at its rate, `data` its own arrays (an array or a named tuple of arrays;
    None: none), `radius` its DTW band radius if it has one.
    """

    def __init__(self, config: ControllerConfig, compiled: Compiled, divider: int,
                 data: Any = None, radius: int = -1) -> None:
        if not isinstance(compiled, Compiled):
            raise TypeError(f"expected the controller's Compiled entry points, got "
                            f"{compiled!r}")
        if divider < 1:
            raise ValueError(f"divider must be >= 1 tick, got {divider}")
        c = config
        self.compiled = compiled
        #: The controller's own arrays (an empty array if it has none).
        self.data: Any = np.zeros(0) if data is None else data
        self.torque = TorqueModel(c.precompression_pct)
        # The Python objects own the arrays the tick updates, so their properties
        # (filtered angles, gains, remaining hold, the window) show the live state.
        self.velocity = HipVelocityFilter(accel_std=c.accel_std, meas_std=c.meas_std)
        self.hold = LockHold(c.hold_s)
        self.window = ObservationWindow(c.window)
        self.state = TickState(
            settings=settings_record(c, divider, self.hold.hold_ticks, radius),
            reference=new_reference(), phase=new_phase(),
            velocity=self.velocity.state, velocity_constants=self.velocity.constants,
            torque_constants=self.torque.constants, hold=self.hold.counters,
            window=self.window.buffer, window_pos=self.window.pos_count, blank=blank_row(),
        )
        #: The output of the last live tick (one `ROW` record; reused).
        self.rows: RecordArray = np.empty(1, dtype=ROW)
        #: The same row as plain float64 values in `ROW_FIELDS` order (a view), which
        #: converts to a list several times faster than the record does.
        self.values: FloatArray = self.rows.view(np.float64)
        self._run = cast(Callable[..., None], compiled.step)

    def reset(self) -> None:
        """Forget filter, window, held locks, tick count, trigger phase and last action."""
        self.velocity.reset()
        self.window.reset()
        self.hold.reset()
        reset_phase(self.state.phase)
        self.state.reference[:] = new_reference()

    @property
    def tick_index(self) -> int:
        """Ticks processed since the last reset (bad ones included)."""
        return int(self.state.phase[0]["tick"])

    def arrays(self) -> list[np.ndarray]:
        """Every array of the state and of the controller's data, in a fixed order (a
        record as one array per field, so that NaN compares equal to NaN in tests)."""
        return _arrays(self.state) + _arrays(self.data)

    def warm_up(self) -> None:
        """Compile the live tick (or load it from numba's cache) on a scratch copy of the
        state, and keep its compiled function."""
        step = self.compiled.step
        args = (_copy(self.state), _copy(self.data), 3100, 3100, 12900, 12900, 0.0, 0,
                np.empty(1, dtype=ROW))
        cast(Callable[..., None], step)(*args)
        # Calling the compiled function directly skips numba's typing of the arguments
        # at every call (named tuples of records are typed in Python, about 2 us).
        sig = tuple(typeof(a) for a in args)
        res: Any = cast(CPUDispatcher, step).overloads.get(sig)
        if res is not None:
            self._run = res.entry_point

    def step(self, c0: int, c1: int, c2: int, c3: int, t: float, status: int) -> np.void:
        """One tick; returns the output row (reused: read it before the next step)."""
        self._run(self.state, self.data, c0, c1, c2, c3, t, status, self.rows)
        return cast(np.void, self.rows[0])
