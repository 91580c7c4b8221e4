"""Expected utilities and the lock decision (paper, "Making Decisions").

`EU(a) = sum_j U(a, model_j, s_curr_j) P(model_j | obs) + U(a, other) P(other | obs)`;
the controller takes `argmax_a EU(a)`.

- Progress `s` is mapped to the nearest progress index `n = floor(100 s + 0.5)`
  (halves round up), clipped to `0..100`.
- A category whose posterior is exactly 0 contributes nothing, even if its progress
  is NaN (a model the onset detector rejected has no meaningful `s_curr`). A NaN
  progress with a positive posterior is an error.
- Ties go to the action with the lower number, so no lock (`a1`) wins any tie: when
  locking is not strictly better the safe choice is to leave the side free.
- Under priors that are not all equal (learned ones), a lock must beat no lock by
  `LOCK_MARGIN` of the terms' size, `sum_c P(c | obs) (|U(a, c)| + |U(a1, c)|)`: then
  rounding cannot make learned priors lock where equal priors do not
  (docs/personalisation.md, "Floating point"). Equal priors decide exactly as before.

Two implementations share these rules: `expected_utilities`/`decide` (NumPy, checked
inputs, for analysis and tests) and `decide_fast` (numba, no allocation, for the tick;
about a microsecond per call once compiled).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from controller.human_data import N_PROGRESS
from controller.tick_record import Action

FloatArray = NDArray[np.float64]

N_ACTIONS = 4
N_CATEGORIES = 4
N_MODELS = 3


#: Relative margin a lock needs under unequal priors. The rounding of the EU sums is a
#: few times 1e-16 of the terms' size; the safety proof under floating point needs the
#: margin above that times (1 + lambda / floor) <= 21 (docs/personalisation.md): 1e-9
#: leaves four orders of magnitude and changes no decision that is not a tie to 1e-9.
LOCK_MARGIN = 1e-9


def lock_margin(priors: NDArray[np.float64] | tuple[float, ...] | list[float]) -> float:
    """The margin a lock needs under `priors`: none under equal priors."""
    p = [float(x) for x in priors]
    return 0.0 if all(x == p[0] for x in p) else LOCK_MARGIN


def progress_index(s: float) -> int:
    """Nearest progress index of `s` in [0, 1] (halves round up, clipped to 0..100)."""
    if math.isnan(s):
        raise ValueError("progress is NaN")
    return min(max(math.floor(s * (N_PROGRESS - 1) + 0.5), 0), N_PROGRESS - 1)


def expected_utilities(
    table: FloatArray, s_curr: FloatArray, posteriors: FloatArray
) -> FloatArray:
    """Expected utility of each action.

    Args:
        table: `(4 actions, 4 categories, 101)` utilities (`UtilityTable.values`).
        s_curr: `(3,)` current progress per model (`MODEL_NAMES` order), in [0, 1].
        posteriors: `(4,)` posteriors of squat, stoop_left, stoop_right, other.

    Returns:
        `(4,)` EU of actions a1..a4. The `other` column is read at `n = 0`: it is
        constant over progress (a minimum over walking).
    """
    table = np.asarray(table, dtype=np.float64)
    s = np.asarray(s_curr, dtype=np.float64)
    p = np.asarray(posteriors, dtype=np.float64)
    if table.shape != (N_ACTIONS, N_CATEGORIES, N_PROGRESS):
        raise ValueError(f"table must have shape (4, 4, 101), got {table.shape}")
    if s.shape != (N_MODELS,):
        raise ValueError(f"s_curr must have shape (3,), got {s.shape}")
    if p.shape != (N_CATEGORIES,):
        raise ValueError(f"posteriors must have shape (4,), got {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError("posteriors contain NaN or inf")
    eu = p[3] * table[:, 3, 0]
    for j in range(N_MODELS):
        if p[j] != 0.0:
            eu = eu + p[j] * table[:, j, progress_index(float(s[j]))]
    return np.asarray(eu, dtype=np.float64)


def decide(eu: FloatArray) -> Action:
    """The action with the largest expected utility; ties go to the lower action number."""
    e = np.asarray(eu, dtype=np.float64)
    if e.shape != (N_ACTIONS,):
        raise ValueError(f"eu must have shape (4,), got {e.shape}")
    if np.isnan(e).any():
        raise ValueError("expected utilities contain NaN")
    return Action(int(np.argmax(e)) + 1)  # argmax returns the first maximum


@numba.njit(cache=True, nogil=True)
def expected_utilities_into(
    table: FloatArray, s_curr: FloatArray, posteriors: FloatArray, out: FloatArray
) -> None:  # pragma: no cover - compiled; covered through decide_fast and tests
    """Allocation-free EU into `out` (4,); same rules as `expected_utilities`."""
    n_last = table.shape[2] - 1
    for a in range(4):
        out[a] = posteriors[3] * table[a, 3, 0]
    for j in range(3):
        pj = posteriors[j]
        if pj == 0.0:
            continue
        s = s_curr[j]
        if s != s:
            raise ValueError("progress is NaN for a model with positive posterior")
        n = math.floor(s * n_last + 0.5)
        n = min(max(n, 0), n_last)
        for a in range(4):
            out[a] += pj * table[a, j, n]


@numba.njit(cache=True, nogil=True)
def _terms_size(table: FloatArray, s_curr: FloatArray, posteriors: FloatArray,
                a: int) -> float:  # pragma: no cover - compiled
    """`sum_c P(c | obs) (|U(a, c)| + |U(a1, c)|)`: what the rounding of EU(a) - EU(a1)
    is relative to."""
    n_last = table.shape[2] - 1
    size = posteriors[3] * (abs(table[a, 3, 0]) + abs(table[0, 3, 0]))
    for j in range(3):
        pj = posteriors[j]
        if pj == 0.0:
            continue
        n = math.floor(s_curr[j] * n_last + 0.5)
        n = min(max(n, 0), n_last)
        size += pj * (abs(table[a, j, n]) + abs(table[0, j, n]))
    return size


@numba.njit(cache=True, nogil=True)
def decide_fast(
    table: FloatArray, s_curr: FloatArray, posteriors: FloatArray, out: FloatArray,
    margin: float = 0.0,
) -> int:  # pragma: no cover - compiled
    """Fill `out` with the EUs and return the chosen action number (1..4).

    Strict `>` keeps the first (lowest-numbered) action on ties. With `margin`
    (`lock_margin(priors)`), a lock action counts only if it beats no lock by `margin`
    times the terms' size. Inputs are not checked (the tick has no time for it); a NaN
    posterior makes every EU NaN, no comparison succeeds and the result is 1, no lock.
    """
    expected_utilities_into(table, s_curr, posteriors, out)
    best = 0
    for a in range(1, 4):
        if out[a] > out[best] and (
                margin == 0.0
                or out[a] - out[0] > margin * _terms_size(table, s_curr, posteriors, a)):
            best = a
    return best + 1


def warm_up() -> None:
    """Compile the numba functions now (call before the control loop, never in a tick)."""
    table = np.zeros((N_ACTIONS, N_CATEGORIES, N_PROGRESS))
    out = np.zeros(N_ACTIONS)
    decide_fast(table, np.zeros(N_MODELS), np.array([0.0, 0.0, 0.0, 1.0]), out)
    decide_fast(table, np.zeros(N_MODELS), np.array([0.0, 0.0, 0.0, 1.0]), out, LOCK_MARGIN)
