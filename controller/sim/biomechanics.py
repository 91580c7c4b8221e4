"""Hip extension moments of the simulated wearer (Nm, extension positive, per leg).

Lifting uses the planar model of `shared/spec/biomechanics.md`:

    M = g (m_HAT r sin(theta_trunk) + m_box d_box) - I_hip theta_trunk''

about both hips together, with theta_trunk the trunk inclination from vertical
(forward positive). The spec writes `+ I_hip theta_trunk''` with the acceleration
counted in the extension direction; here flexion is positive, hence the minus sign:
decelerating the downward bend and accelerating the trunk up both need extension.

Assumptions (the project's own, chosen to reproduce the spec's magnitudes):
- Winter's table 4.1 anthropometrics: m_HAT = 0.678 m, hip height 0.530 H, shoulder
  height 0.818 H, HAT centre of mass at 0.626 of hip-to-shoulder length, radius of
  gyration 0.496 of that length about the centre of mass.
- The box is a point mass at horizontal distance `d_box = 0.114 H + 0.6 L sin(theta_trunk)`
  from the hips (held against the belly when upright; below the shoulders and a little
  behind them when bent). Its inertia about the hips is added to I_hip.
- The legs' own segments are ignored (the spec's model does); so are knee and ankle.
- Split between legs: squat evenly (plus the participant's asymmetry), asymmetric stoop
  `box_side_share` (55-65 %) on the box-side leg, for the whole moment.
- Walking and stairs: the normative curves (Nm/kg) below, read from Winter and
  Schwartz et al. 2008 (walking) and Riener et al. 2002 / Costigan et al. 2002 (stairs),
  scaled by body mass and a per-participant factor. The planar model does not apply.
With this model a 75 kg, 1.75 m wearer needs about 2.2 Nm/kg (squat, 10 kg), 2.0 Nm/kg
(squat, 5 kg) and 3.1-3.4 Nm/kg (stoop, 10 kg) at peak, as in the spec.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

FloatArray = NDArray[np.float64]
G = 9.81


@dataclass(frozen=True, slots=True)
class Anthropometrics:
    """Segment parameters of the head-arms-trunk (HAT) about the hips (Winter)."""

    mass_kg: float
    height_m: float
    m_hat: float
    trunk_length: float  # hip to shoulder
    r_com: float  # hip to HAT centre of mass
    i_hip: float  # HAT moment of inertia about the hip axis

    @classmethod
    def from_body(cls, mass_kg: float, height_m: float) -> Anthropometrics:
        """Winter's proportions for a body of this mass and height."""
        if mass_kg <= 0 or height_m <= 0:
            raise ValueError("mass and height must be positive")
        m_hat = 0.678 * mass_kg
        length = (0.818 - 0.530) * height_m
        r = 0.626 * length
        rho = 0.496 * length
        return cls(mass_kg, height_m, m_hat, length, r, m_hat * (rho * rho + r * r))

    def box_distance(self, trunk: FloatArray) -> FloatArray:
        """Horizontal hip-to-box distance (m) at trunk inclination `trunk` (rad)."""
        return 0.114 * self.height_m + 0.6 * self.trunk_length * np.sin(trunk)


def lift_hip_moment(
    body: Anthropometrics, trunk: FloatArray, box_kg: FloatArray, dt: float
) -> FloatArray:
    """Total hip extension moment of both hips (Nm) from the planar model.

    `trunk` (rad) and `box_kg` are sampled every `dt` seconds; the trunk must be smooth
    because its second derivative is taken numerically.
    """
    trunk = np.asarray(trunk, dtype=np.float64)
    box = np.asarray(box_kg, dtype=np.float64)
    d_box = body.box_distance(trunk)
    acc = np.gradient(np.gradient(trunk, dt), dt) if trunk.size > 2 else np.zeros_like(trunk)
    inertia = body.i_hip + box * d_box * d_box
    static = G * (body.m_hat * body.r_com * np.sin(trunk) + box * d_box)
    return np.asarray(static - inertia * acc, dtype=np.float64)


def split_moment(total: FloatArray, share_left: FloatArray | float) -> FloatArray:
    """Per-leg moments (K, 2) from the total and the left leg's share."""
    share = np.broadcast_to(np.asarray(share_left, dtype=np.float64), np.shape(total))
    return np.stack([total * share, total * (1.0 - share)], axis=1)


def _periodic(points: list[tuple[float, float]]) -> CubicSpline:
    x = np.array([p[0] for p in points] + [1.0])
    y = np.array([p[1] for p in points] + [points[0][1]])
    return CubicSpline(x, y, bc_type="periodic")


# Hip extension moment over one gait cycle of the leg (phase 0 = its foot contact),
# Nm/kg. Walking: +0.75 in early stance, -0.85 near toe-off (Winter; Schwartz 2008).
GAIT_MOMENT_NM_PER_KG: dict[str, CubicSpline] = {
    "walk": _periodic(
        [
            (0.00, 0.25),
            (0.06, 0.75),
            (0.15, 0.45),
            (0.30, 0.00),
            (0.45, -0.55),
            (0.53, -0.85),
            (0.62, -0.45),
            (0.72, -0.10),
            (0.85, 0.15),
            (0.94, 0.35),
        ]
    ),
    # Stair ascent: pulling the body up onto the step, peak about 1.15 Nm/kg (Costigan).
    "stairs_up": _periodic(
        [
            (0.00, 0.40),
            (0.08, 1.15),
            (0.20, 0.80),
            (0.35, 0.30),
            (0.50, -0.10),
            (0.60, -0.35),
            (0.68, -0.20),
            (0.80, 0.05),
            (0.92, 0.20),
        ]
    ),
    # Stair descent: smaller hip moments, the knee does the work.
    "stairs_down": _periodic(
        [
            (0.00, 0.10),
            (0.10, 0.55),
            (0.30, 0.15),
            (0.50, -0.20),
            (0.65, -0.05),
            (0.80, 0.10),
            (0.92, 0.20),
        ]
    ),
}


def gait_moment(kind: str, phase: FloatArray, mass_kg: float, scale: float = 1.0) -> FloatArray:
    """Hip extension moment (Nm) of one leg at gait `phase` (cycles, any real number)."""
    try:
        curve = GAIT_MOMENT_NM_PER_KG[kind]
    except KeyError:
        raise ValueError(f"no gait moment curve for {kind!r}") from None
    frac = np.mod(np.asarray(phase, dtype=np.float64), 1.0)
    return np.asarray(curve(frac) * mass_kg * scale, dtype=np.float64)


def nm_per_kg(moment: FloatArray | float, mass_kg: float) -> FloatArray:
    """Moment normalised by body mass, the unit the literature reports."""
    return np.asarray(moment, dtype=np.float64) / mass_kg

