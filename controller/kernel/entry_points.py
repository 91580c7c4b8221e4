"""A controller's two compiled entry points, built from its decision step.

Every controller runs the same two functions around its own `decide`: `step` (one live
tick) and `batch` (the batch replay, the simulated mechanism stepped between ticks). They
are written once, here, as plain Python templates; `entry_points(decide)` compiles a copy
of each in which the name `decide` is that controller's decision, so numba inlines it as
if the controller module had written the function itself.

Why a copy with its own globals, not a closure or an argument: numba caches a compiled
function under an index keyed by its code and, for a closure, by the pickled cell
contents. A numba function pickles with a per-process identifier, so a closure over
`decide` never hits the cache in the next process (measured: a miss and a new cache
entry in every process); passing `decide` as an argument cannot be cached either
(`docs/controller-kernel.md`). A copy whose globals name `decide` is a plain function:
its cache key is its code and signature. The copy takes its file and name from the
decision (`umc.decide_step`), so that each controller has its own cache files next to
its module and editing the controller's module invalidates them.
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any

from numba import njit
from numba.core.dispatcher import Dispatcher
from numba.core.registry import CPUDispatcher

from controller.kernel.core import Compiled
from controller.kernel.tick import begin, finish, replay_sample


def decide(state, data, row) -> tuple[bool, int, int]:  # type: ignore[no-untyped-def]
    """The name the templates call; `entry_points` binds it to a controller's decision.
    Reaching this body means a template was called unbound: a programming error."""
    raise TypeError("call the pair that entry_points(decide) returns, not its template")


def step(state, data, c0, c1, c2, c3, t, status, rows) -> None:  # type: ignore[no-untyped-def]
    """One live tick with the controller's decision (`controller.kernel.tick`)."""
    if begin(state, c0, c1, c2, c3, t, status, rows, 0):
        finish(state, decide(state, data, rows[0]), status, rows, 0)


def batch(state, data, plant, plant_k, layout, t, q, rows, counts, statuses) -> None:  # type: ignore[no-untyped-def]
    """The batch replay with the controller's decision (`controller.kernel.tick`)."""
    for k in range(t.shape[0]):
        c0, c1, c2, c3, status = replay_sample(plant, plant_k, layout, q, rows, counts,
                                               statuses, k)
        if begin(state, c0, c1, c2, c3, t[k], status, rows, k):
            finish(state, decide(state, data, rows[k]), status, rows, k)


def _bind(template: Callable[..., None], decision: Dispatcher[Any]) -> Dispatcher[Any]:
    """`template` compiled with `decide` meaning `decision`, filed under the decision's
    module and name (`<module file>.<decision>_<template>`) for numba's cache."""
    own: Any = decision.py_func
    name = f"{own.__name__}_{template.__name__}"
    code = template.__code__.replace(co_filename=own.__code__.co_filename, co_name=name,
                                     co_qualname=name)
    scope = dict(template.__globals__, decide=decision)
    copy = types.FunctionType(code, scope, name)
    copy.__module__ = own.__module__
    copy.__qualname__ = name
    copy.__doc__ = template.__doc__
    return njit(cache=True, nogil=True)(copy)


def entry_points(decision: Dispatcher[Any]) -> Compiled:
    """The `Compiled` pair (`step`, `batch`) of a controller whose decision step is
    `decision`, an `@njit(cache=True, nogil=True)` function
    `decide(state, data, row) -> (ran, action, flags)`."""
    if not isinstance(decision, CPUDispatcher):
        raise TypeError(f"entry_points needs a decision compiled with numba's @njit, "
                        f"got {decision!r}")
    return Compiled(_bind(step, decision), _bind(batch, decision))
