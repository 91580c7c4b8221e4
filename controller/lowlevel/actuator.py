"""MACCEPA 2.0 actuator with a circular profile disk: torque from spring deflection.

Equations and parameters of the paper's "Hardware" section, written out. Lengths in
millimetres inside, torque returned in Nm.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, overload

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class MaccepaParams:
    """Geometry and springs of one side. Defaults are the paper's prototype."""

    lever_arm_mm: float = 10.0  # B
    roller_distance_mm: float = 30.0  # C
    disk_radius_mm: float = 7.5  # R
    stiffness_n_per_mm: float = 2 * 33.6  # two springs in parallel
    max_compression_mm: float = 22.0
    ratchet_teeth: int = 40

    def __post_init__(self) -> None:
        if not 0 < self.lever_arm_mm < self.roller_distance_mm:
            raise ValueError("lever arm B must be positive and shorter than roller distance C")
        if self.disk_radius_mm <= 0 or self.stiffness_n_per_mm <= 0:
            raise ValueError("disk radius and stiffness must be positive")
        if self.max_compression_mm <= 0 or self.ratchet_teeth <= 0:
            raise ValueError("max compression and ratchet teeth must be positive")

    @property
    def tooth_angle(self) -> float:
        """Angular pitch of the ratchet in radians (9 degrees for 40 teeth)."""
        return 2.0 * math.pi / self.ratchet_teeth


PAPER_ACTUATOR = MaccepaParams()


def _check_precompression(precompression_pct: float) -> float:
    if not (0.0 <= precompression_pct <= 100.0) or math.isnan(precompression_pct):
        raise ValueError(f"precompression must be within 0..100 %, got {precompression_pct}")
    return precompression_pct


def spring_elongation_mm(
    alpha: FloatArray | float, p: MaccepaParams = PAPER_ACTUATOR
) -> FloatArray:
    """Spring compression added by deflection `alpha` (rad); zero at alpha = 0."""
    a = np.asarray(alpha, dtype=np.float64)
    B, C, R = p.lever_arm_mm, p.roller_distance_mm, p.disk_radius_mm
    i = C * np.cos(a) - B
    h = C * np.sin(a) - R
    e = np.sqrt(i * i + h * h - R * R)
    lam = np.pi / 2 - np.arctan(e / R) + np.arctan2(h, i)
    return np.asarray(e + R * lam - (C - B), dtype=np.float64)


@overload
def maccepa_torque(
    alpha: float, precompression_pct: float, params: MaccepaParams = ...
) -> float: ...
@overload
def maccepa_torque(
    alpha: FloatArray, precompression_pct: float, params: MaccepaParams = ...
) -> FloatArray: ...
def maccepa_torque(
    alpha: FloatArray | float, precompression_pct: float, params: MaccepaParams = PAPER_ACTUATOR
) -> FloatArray | float:
    """Extension torque (Nm) at deflection `alpha` (rad) for a precompression in percent
    of the 22 mm maximum compression.

    Deflections at or below zero give no torque (the ratchet does not hold there).
    Beyond the compression limit the torque is clamped at the limit's value: the
    mechanism cannot go further (the simulator reports that as a hard stop).

    >>> round(maccepa_torque(math.radians(30), 0.0), 2)
    1.79
    """
    pct = _check_precompression(precompression_pct)
    if isinstance(alpha, float):  # Python float or np.float64: the per-tick path
        return _scalar_torque(alpha, pct, params)
    scalar = np.ndim(alpha) == 0
    a = np.asarray(alpha, dtype=np.float64)
    if np.isnan(a).any():
        raise ValueError("deflection alpha contains NaN")
    p = params
    pre = p.max_compression_mm * pct / 100.0
    a_lim = max_deflection(pct, p)
    a_c = np.clip(a, 0.0, a_lim)
    torque = np.where(a > 0.0, _clipped_torque(a_c, pre, p), 0.0)
    if scalar:
        return float(torque)
    return np.asarray(torque, dtype=np.float64)


def _scalar_torque(alpha: float, pct: float, p: MaccepaParams) -> float:
    """`maccepa_torque` of one deflection, the same operations in the same order on
    NumPy scalars instead of 0-d arrays: the same ufuncs and IEEE arithmetic give the
    same bits (tests/controller/lowlevel/test_actuator.py compares them with the array
    code), at a tenth of the 0-d arrays' overhead per call."""
    if alpha != alpha:
        raise ValueError("deflection alpha contains NaN")
    if not alpha > 0.0:
        return 0.0
    a_lim = max_deflection(pct, p)
    a_c = np.float64(alpha if alpha < a_lim else a_lim)  # np.clip of a positive value
    pre = p.max_compression_mm * pct / 100.0
    return float(_clipped_torque(a_c, pre, p))


def _clipped_torque(a_c: Any, pre: float, p: MaccepaParams) -> Any:
    """The mechanism's torque (Nm) at clipped deflections `a_c` (a NumPy scalar or an
    array: the same ufuncs either way, so both paths give the same bits) with
    precompression `pre` (mm)."""
    B, C, R = p.lever_arm_mm, p.roller_distance_mm, p.disk_radius_mm
    i = C * np.cos(a_c) - B
    h = C * np.sin(a_c) - R
    e = np.sqrt(i * i + h * h - R * R)
    lam = np.pi / 2 - np.arctan(e / R) + np.arctan2(h, i)
    kappa = lam - a_c
    elong = e + R * lam - (C - B)
    force = p.stiffness_n_per_mm * (pre + elong)  # N
    return force * C * np.sin(kappa) / 1000.0  # N mm -> N m


def max_deflection(precompression_pct: float, params: MaccepaParams = PAPER_ACTUATOR) -> float:
    """Deflection (rad) at which precompression plus elongation reaches the limit.

    Found by root finding once per precompression and geometry and remembered: the
    simulator asks for it with every torque, 100 times a second per side."""
    return _max_deflection(_check_precompression(precompression_pct), params)


@functools.lru_cache(maxsize=1024)
def _max_deflection(pct: float, params: MaccepaParams) -> float:
    room = params.max_compression_mm * (1.0 - pct / 100.0)
    if room <= 0.0:
        return 0.0

    def excess(a: float) -> float:
        return float(spring_elongation_mm(a, params)) - room

    # The elongation grows monotonically up to about 150 degrees, where atan2 wraps;
    # every admissible precompression reaches the limit well before that.
    hi = math.radians(150.0)
    # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
    from scipy.optimize import brentq

    return float(brentq(excess, 0.0, hi, xtol=1e-10))


def at_hard_stop(
    alpha: float, precompression_pct: float, params: MaccepaParams = PAPER_ACTUATOR
) -> bool:
    """True when the spring is fully compressed at deflection `alpha`."""
    return alpha >= max_deflection(precompression_pct, params) - 1e-9


# Constants of `torque_at`: limit deflection, precompression (mm), B, C, R (mm), k (N/mm).
_A_MAX, _PRE, _B, _C, _R, _K = range(6)


@njit("float64(float64, float64[::1])", cache=True, nogil=True)
def torque_at(alpha: float, k: FloatArray) -> float:
    """Torque (Nm) at deflection `alpha` (rad) for the constants `k` of a `TorqueModel`;
    0 for alpha <= 0 or NaN. The one scalar implementation, shared by `TorqueModel` and
    the compiled control tick (`controller.kernel.tick`)."""
    if not alpha > 0.0:
        return 0.0
    a_max = k[_A_MAX]
    a = a_max if a_max < alpha else alpha
    B = k[_B]
    C = k[_C]
    R = k[_R]
    i = C * math.cos(a) - B
    h = C * math.sin(a) - R
    e = math.sqrt(i * i + h * h - R * R)
    lam = math.pi / 2 - math.atan(e / R) + math.atan2(h, i)
    force = k[_K] * (k[_PRE] + e + R * lam - (C - B))
    return force * C * math.sin(lam - a) / 1000.0


class TorqueModel:
    """`maccepa_torque` for one precompression as plain scalar math, for the 100 Hz tick.

    The NumPy version costs microseconds per call in overhead; this one (`torque_at`,
    compiled) well under one. The limit deflection is found once, at construction.
    """

    def __init__(self, precompression_pct: float, params: MaccepaParams = PAPER_ACTUATOR) -> None:
        self.precompression_pct = _check_precompression(precompression_pct)
        self.params = params
        self.alpha_max = max_deflection(precompression_pct, params)
        p = params
        #: The constants `torque_at` reads, in its order.
        self.constants = np.array([
            self.alpha_max, p.max_compression_mm * precompression_pct / 100.0,
            p.lever_arm_mm, p.roller_distance_mm, p.disk_radius_mm, p.stiffness_n_per_mm,
        ])

    def __call__(self, alpha: float) -> float:
        """Torque (Nm) at deflection `alpha` (rad); 0 for alpha <= 0 or NaN."""
        return float(torque_at(float(alpha), self.constants))
