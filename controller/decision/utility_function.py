"""Utilities U(a, category, s_n) of the four lock actions (paper, "Calculating Utilities"
and its appendix).

Per leg and motion, from the mean human hip angle `theta(s_n)` and hip extension torque
`tau(s_n)` (`HumanMotionData`) and the actuator model `tau_exo(alpha)`:

- lock at `c`: `alpha_n = theta_n - theta_c` for `n >= c`; the lock releases for good at
  the first `n` with `alpha_n < 0`; `q_lock(c) = -sum_{n>=c} (tau_n - tau_exo(alpha_n))^2`
  with `tau_exo = 0` once released.
- supporting leg, no lock: `-tau_c^2 + q_lock(c + 1)`, and `-tau_100^2` at the end.
- non-supporting leg, no lock: `-sum_{n>=c} tau_n^2`.

Squat: both legs support; stoop_left: the left leg; stoop_right: the right. Walking
uses the appendix's value iteration (neither leg is assumed to support), and the
category `other` is derived from the walking utilities by `other_rule` (below).

Choices the paper leaves open, made here:

- **Signed torques.** `tau_hum` is the hip *extension* torque, negative when the human
  produces flexion torque. The exoskeleton only gives extension torque (`>= 0`). The
  residual `tau_hum - tau_exo` is used as signed: when the human is flexing (or needs
  less than the exo gives), a locked side's torque adds to what the human must produce
  and is penalised, which is what the wearer would feel. Nothing is clipped.
- **Continuous deflection.** The ratchet's 9 degree teeth are ignored, as in the
  paper's equations; `alpha` is the human angle change since the lock.
- **Compression limit.** The human trajectory is taken as given; beyond the 22 mm
  limit the actuator model returns the limit's torque (`maccepa_torque` clamps).
- **Value iteration** follows the appendix's MDP literally: after an automatic
  release the side is unlocked and may be locked again. For lifts whose angle falls
  monotonically after the peak this changes nothing (a relock during extension is
  released at once), so the general method equals the closed form whenever the
  paper's assumptions hold (locking as soon as possible is optimal for a supporting
  leg, never locking for a non-supporting one). `assumption_gap` in the set's `meta`
  reports, per lifting motion, the largest difference between the two.
- **`other`: a stated departure from the literal rule** `U(a, other) = min_s U(a,
  walking, s)` (`other_rule="paper-literal"`, kept as an option). Walking utilities
  sum over the rest of the cycle, so every action's minimum sits at `s = 0` and the
  rule compares actions at one arbitrary phase (left heel strike). On the simulated
  reference data that is the right hip's maximal extension, where locking beats the
  value-iteration baseline (lock one sample later) by 3.6 Nm^2 at 0 % precompression
  and 2.1 Nm^2 at 25 % (checked again after the per-leg lifting model: walking data
  did not change), so `other` prefers locking: the opposite of the heuristic's
  purpose, and with `other` the most probable category the UMC would lock during
  unknown motions. That is why the literal rule is not the default. Decisions depend only
  on differences to no-lock within a category, so the default `"worst-difference"`
  keeps `U(no_lock, other)` literal and adds, per action, the worst case over walking
  progress of `U(a, walking, s) - U(no_lock, walking, s)` (walking still by value
  iteration). All actions tie at the last sample, so this is `<= 0`: a lock is never
  preferred in `other`, but only penalised if some phase makes it cost (otherwise a
  tie). `meta` stores the rule and each action's penalty.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from controller.human_data import HUMAN_MOTIONS, LEGS, N_PROGRESS, HumanMotionData
from controller.lowlevel.actuator import PAPER_ACTUATOR, MaccepaParams, maccepa_torque
from controller.tick_record import ACTION_NAMES, CATEGORY_NAMES, MODEL_NAMES, Action

FloatArray = NDArray[np.float64]

FORMAT_NAME = "exostudy.utility_set"
FORMAT_VERSION = 1

#: Which legs (left, right) carry the weight in each lifting motion.
SUPPORTING_LEGS: dict[str, tuple[bool, bool]] = {
    "squat": (True, True),
    "stoop_left": (True, False),
    "stoop_right": (False, True),
}

#: Per action, whether it locks the (left, right) side now.
ACTION_LOCKS: tuple[tuple[bool, bool], ...] = tuple(a.locks for a in Action)

ProgressCallback = Callable[[float], None]

#: How `U(a, other)` is derived from the walking utilities (see the module docstring).
OtherRule = Literal["worst-difference", "paper-literal"]
OTHER_RULES: tuple[OtherRule, ...] = ("worst-difference", "paper-literal")
DEFAULT_OTHER_RULE: OtherRule = "worst-difference"


def _exo_torque_matrix(
    theta: FloatArray, precompression_pct: float, params: MaccepaParams
) -> FloatArray:
    """`T[m, n] = tau_exo(theta_n - theta_m)`: torque at `n` of a side locked at `m`."""
    alpha = theta[None, :] - theta[:, None]
    return np.asarray(maccepa_torque(alpha, precompression_pct, params), dtype=np.float64)


def lock_total_reward(
    theta: FloatArray, tau: FloatArray, precompression_pct: float,
    params: MaccepaParams = PAPER_ACTUATOR,
) -> FloatArray:
    """Closed-form `q(s_c, lock)` for every `c` of one leg (paper eq. "total reward lock").

    Args:
        theta: `(N,)` hip flexion (rad) over progress.
        tau: `(N,)` hip extension torque (Nm) over progress.

    Returns:
        `(N,)` total reward (Nm^2, <= 0).
    """
    theta = np.asarray(theta, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    n_s = theta.shape[0]
    alpha = theta[None, :] - theta[:, None]  # [c, n]
    idx = np.arange(n_s)
    ahead = idx[None, :] >= idx[:, None]
    # Locked from c up to (excluding) the first n >= c with alpha < 0, then free for good.
    released = np.cumsum((alpha < 0.0) & ahead, axis=1) > 0
    locked = ahead & ~released
    t_exo = np.where(locked, _exo_torque_matrix(theta, precompression_pct, params), 0.0)
    resid = tau[None, :] - t_exo
    # Sum each row sequentially from the end (np.cumsum is a running sum). Every path
    # to the same future then adds the same numbers in the same order, so a lock that
    # releases at once equals "no lock" bit for bit: no action wins a tie by rounding.
    suffix = np.cumsum((resid * resid)[:, ::-1], axis=1)[:, ::-1]
    return np.asarray(-np.diagonal(suffix), dtype=np.float64)


def closed_form_leg_rewards(
    theta: FloatArray, tau: FloatArray, supporting: bool, precompression_pct: float,
    params: MaccepaParams = PAPER_ACTUATOR,
) -> tuple[FloatArray, FloatArray]:
    """`(q(s_c, no-lock), q(s_c, lock))` of one leg of a lifting motion, each `(N,)`."""
    tau = np.asarray(tau, dtype=np.float64)
    q_lock = lock_total_reward(theta, tau, precompression_pct, params)
    if supporting:
        q_keep = -tau * tau
        q_keep[:-1] += q_lock[1:]
    else:
        q_keep = -np.cumsum((tau * tau)[::-1])[::-1]  # same running sum as above
    return np.asarray(q_keep, dtype=np.float64), q_lock


def value_iteration_leg(
    theta: FloatArray, tau: FloatArray, precompression_pct: float,
    params: MaccepaParams = PAPER_ACTUATOR, max_sweeps: int | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The appendix's general method for one leg: `(q(n, keep), q(n, lock))` at `l = 0`.

    States are `(l = 0, n)` and `(l = 1, n_lock, n)` (the lock angle is
    `theta[n_lock]`); actions keep (`u = 0`) and lock (`u = 1`); reward
    `-(tau_n - tau_exo(alpha_n))^2` with `tau_exo = 0` while unlocked; locking at `n`
    makes `l_{n+1} = 1` with `theta_lock = theta_n`; a locked side whose `alpha_n < 0`
    is unlocked at `n + 1`; discount 1; the motion ends after `n = N - 1`.

    The Bellman update is applied to every state at once (synchronous sweeps) until
    nothing changes; with progress always advancing that takes `N + 1` sweeps.
    """
    theta = np.asarray(theta, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    n_s = theta.shape[0]
    alpha = theta[None, :] - theta[:, None]  # [n_lock, n]
    r1 = -(tau[None, :] - _exo_torque_matrix(theta, precompression_pct, params)) ** 2
    r0 = -tau * tau
    release = alpha < 0.0
    # Value arrays with a terminal column n = N of zeros.
    v0 = np.zeros(n_s + 1)
    v1 = np.zeros((n_s, n_s + 1))
    q_keep = np.zeros(n_s)
    q_lock = np.zeros(n_s)
    sweeps = max_sweeps if max_sweeps is not None else n_s + 2
    idx = np.arange(n_s)
    for _ in range(sweeps):
        q_keep_new = r0 + v0[1:]
        q_lock_new = r0 + v1[idx, idx + 1]
        v1_new = np.zeros_like(v1)
        v1_new[:, :n_s] = r1 + np.where(release, v0[None, 1:], v1[:, 1:])
        v0_new = np.zeros_like(v0)
        v0_new[:n_s] = np.maximum(q_keep_new, q_lock_new)
        converged = (
            np.array_equal(v0_new, v0) and np.array_equal(v1_new, v1)
            and np.array_equal(q_keep_new, q_keep) and np.array_equal(q_lock_new, q_lock)
        )
        v0, v1, q_keep, q_lock = v0_new, v1_new, q_keep_new, q_lock_new
        if converged:
            break
    return q_keep, q_lock


def _leg_table(q_keep: FloatArray, q_lock: FloatArray, leg: int) -> FloatArray:
    """`(4, N)` reward of this leg under each action."""
    return np.stack([q_lock if locks[leg] else q_keep for locks in ACTION_LOCKS])


def other_utilities(walking: FloatArray, rule: OtherRule = DEFAULT_OTHER_RULE) -> FloatArray:
    """`(4,)` U(a, other) from the `(4, N)` walking utilities (rows in `Action` order).

    `"paper-literal"`: `min_s U(a, walking, s)` per action. `"worst-difference"`:
    `min_s U(no_lock, walking, s) + min_s (U(a, walking, s) - U(no_lock, walking, s))`,
    which equals the literal value for no-lock and never exceeds it for a lock when
    the last sample ties (it does for value-iteration utilities).
    """
    w = np.asarray(walking, dtype=np.float64)
    if rule == "paper-literal":
        return np.asarray(w.min(axis=1), dtype=np.float64)
    if rule == "worst-difference":
        base = w[0]
        return np.asarray(base.min() + (w - base[None, :]).min(axis=1), dtype=np.float64)
    raise ValueError(f"other_rule must be one of {OTHER_RULES}, got {rule!r}")


@dataclass(frozen=True)
class UtilityTable:
    """`values[a, j, n]` = U(action a+1, category j, s_n), categories in `CATEGORY_NAMES`.

    The `other` column is constant over `n` (derived from walking, see `other_rule`).
    """

    values: FloatArray

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.values, dtype=np.float64)
        shape = (len(Action), len(CATEGORY_NAMES), N_PROGRESS)
        if v.shape != shape:
            raise ValueError(f"utility table must have shape {shape}, got {v.shape}")
        if not np.isfinite(v).all():
            raise ValueError("utility table contains NaN or inf")
        object.__setattr__(self, "values", v)

    def utility(self, action: Action, category: str, n: int) -> float:
        """One entry, by action, category name and progress index."""
        return float(self.values[int(action) - 1, CATEGORY_NAMES.index(category), n])

    def best_actions(self) -> NDArray[np.int64]:
        """`(4, N)` best action number per category and progress (ties: lower number)."""
        return np.asarray(np.argmax(self.values, axis=0) + 1, dtype=np.int64)


@dataclass(frozen=True)
class UtilitySet:
    """A utility table and everything it was computed from."""

    table: UtilityTable
    precompression_pct: float
    actuator: MaccepaParams
    human_source: str
    human_version: str
    created: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """Versioned JSON document."""
        return {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "created": self.created,
            "precompression_pct": self.precompression_pct,
            "actuator": asdict(self.actuator),
            "human_data": {"source": self.human_source, "version": self.human_version},
            "actions": list(ACTION_NAMES),
            "categories": list(CATEGORY_NAMES),
            "n_progress": N_PROGRESS,
            "utilities_nm2": self.table.values.tolist(),
            "meta": self.meta,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> UtilitySet:
        """Inverse of `to_json`; refuses other formats, versions and orders."""
        if data.get("format") != FORMAT_NAME:
            raise ValueError(f"not an {FORMAT_NAME} document (format={data.get('format')!r})")
        if data.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"unsupported format_version {data.get('format_version')!r}")
        if list(data.get("actions", [])) != list(ACTION_NAMES):
            raise ValueError(f"actions must be {list(ACTION_NAMES)}")
        if list(data.get("categories", [])) != list(CATEGORY_NAMES):
            raise ValueError(f"categories must be {list(CATEGORY_NAMES)}")
        try:
            human = data["human_data"]
            return cls(
                table=UtilityTable(np.asarray(data["utilities_nm2"], dtype=np.float64)),
                precompression_pct=float(data["precompression_pct"]),
                actuator=MaccepaParams(**data["actuator"]),
                human_source=str(human["source"]),
                human_version=str(human["version"]),
                created=str(data.get("created", "")),
                meta=dict(data.get("meta", {})),
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(f"utility set document: bad or missing field {exc}") from exc

    def save(self, path: Path) -> None:
        """Write as JSON."""
        path.write_text(json.dumps(self.to_json()))

    @classmethod
    def load(cls, path: Path) -> UtilitySet:
        """Read a file written by `save`."""
        return cls.from_json(json.loads(path.read_text()))


def compute_utilities(
    human: HumanMotionData,
    precompression_pct: float,
    params: MaccepaParams = PAPER_ACTUATOR,
    progress: ProgressCallback | None = None,
    other_rule: OtherRule = DEFAULT_OTHER_RULE,
) -> UtilitySet:
    """Compute the utility table for one actuator setting.

    Args:
        human: mean hip angle and torque per motion and leg.
        precompression_pct: spring precompression in percent of 22 mm.
        params: actuator geometry.
        progress: optional callback receiving the fraction done (0..1), so a
            background job can report; called a handful of times.
        other_rule: how `U(a, other)` is derived from walking (module docstring).

    Returns:
        The set, with `meta["assumption_gap"]` (per lifting motion, the largest
        `|value iteration - closed form|` over legs, actions and progress, Nm^2),
        `meta["other_rule"]` and `meta["other_penalty"]` (per action name,
        `U(a, other) - U(no_lock, other)`, Nm^2).
    """
    if other_rule not in OTHER_RULES:
        raise ValueError(f"other_rule must be one of {OTHER_RULES}, got {other_rule!r}")
    values = np.zeros((len(Action), len(CATEGORY_NAMES), N_PROGRESS))
    gap: dict[str, float] = {}
    steps = 2 * len(HUMAN_MOTIONS)
    done = 0

    def report() -> None:
        if progress is not None:
            progress(done / steps)

    report()
    for j, motion in enumerate(MODEL_NAMES):
        mi = HUMAN_MOTIONS.index(motion)
        worst = 0.0
        for leg in range(len(LEGS)):
            theta, tau = human.theta[mi, leg], human.tau[mi, leg]
            keep, lock = closed_form_leg_rewards(
                theta, tau, SUPPORTING_LEGS[motion][leg], precompression_pct, params
            )
            values[:, j, :] += _leg_table(keep, lock, leg)
            vi_keep, vi_lock = value_iteration_leg(theta, tau, precompression_pct, params)
            worst = max(worst, float(np.max(np.abs(vi_keep - keep))),
                        float(np.max(np.abs(vi_lock - lock))))
            done += 1
            report()
        gap[motion] = worst
    mi = HUMAN_MOTIONS.index("walking")
    walking = np.zeros((len(Action), N_PROGRESS))
    for leg in range(len(LEGS)):
        keep, lock = value_iteration_leg(
            human.theta[mi, leg], human.tau[mi, leg], precompression_pct, params
        )
        walking += _leg_table(keep, lock, leg)
        done += 1
        report()
    other = other_utilities(walking, other_rule)
    values[:, CATEGORY_NAMES.index("other"), :] = other[:, None]
    done = steps
    report()
    return UtilitySet(
        table=UtilityTable(values),
        precompression_pct=float(precompression_pct),
        actuator=params,
        human_source=human.source,
        human_version=human.version,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        meta={
            "assumption_gap": gap,
            "other_rule": other_rule,
            "other_penalty": {
                name: float(other[a] - other[0]) for a, name in enumerate(ACTION_NAMES)
            },
        },
    )
