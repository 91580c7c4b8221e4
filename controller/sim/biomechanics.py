"""Hip extension moments of the simulated wearer (Nm, extension positive, per leg).

Why a model: no lab dataset ships with the project, yet the utilities the controllers
decide with depend on how each *leg* is loaded. A free "share" of the load per leg
decides the paper's asymmetric-stoop result by itself, so the split here follows from
statics and the geometry of the paper's task, with inputs only from anthropometric
tables, the protocol and the box mass.

Total moment about both hips (sagittal, top-down, Winter's HAT model):

    M = g (m_HAT r sin(theta_trunk) + m_box d_box) - (I_hip + m_box d_box^2) theta_trunk''

theta_trunk is the trunk inclination from vertical (forward positive); the minus sign
is because flexion is positive here: slowing the bend and raising the trunk both need
extension. This is what the legs together must supply about the pelvis' flexion axis.

Inputs (Winter 2009, table 4.1 and figure 4.1, fractions of mass m and height H):
HAT mass 0.678 m; hip height 0.530 H, shoulder height 0.818 H, knee height 0.285 H
(so thigh length 0.245 H); HAT centre of mass at 0.626 and radius of gyration 0.496 of
the hip-to-shoulder length; shoulder width 0.259 H; foot width 0.055 H. Hip joint
centres 0.10 H apart (Bell et al. 1990 place them at 36 % of the inter-ASIS distance
either side of the midline; inter-ASIS about 0.14 H).

Per-leg split, by task:

- **Squat and standing** (feet parallel at shoulder width, symmetric posture): the
  upper body's load lies on the midline, so by the frontal lever rule each hip carries
  half of it at the same sagittal lever arm: half the moment each.
- **Asymmetric stoop** (the paper's protocol: feet at 90 degrees to each other, the box
  in front of one foot; shoulder width between the feet, as the paper's source text
  has it in a passage left out of the final version). Two facts of this geometry decide the
  split. (1) The trunk bends *towards the box*: from the hip midpoint to a point on
  the box-side foot's line (half the stance width to that side) at the box's reach
  `d_reach` ahead. The upper body's load (HAT and box) therefore moves to the box side
  by `y_u = x_u (w / 2) / d_reach`, with `x_u` its forward lever arm. By the frontal
  lever rule between the hip joint centres (pelvis as a beam, abductor moments
  neglected), the other hip carries `F = W_u (1/2 - y_u / h)`, and nothing once the
  load lies beyond the box-side hip. (2) The other foot is turned out by 90 degrees,
  so in the direction of the bend it reaches only half a foot width either side of
  its ankle. That leg's hip moment about the flexion axis is its load times the
  forward distance from the hip to its centre of pressure: the hip moves back by `D`
  in a stoop (the whole-body centre of mass stays above the feet, the legs rotating
  about the ankles), so the lever arm is `max(0, D - w_foot / 2)`. The box-side hip
  supplies the rest of the total. Both hips together still supply exactly `M`.
  `D` follows from keeping the whole-body centre of mass above the ankles:
  `D = W_u x_u / (W_u + 0.8 m_thighs + 0.3 m_shanks)` (thigh and shank centres of mass
  at about 0.8 and 0.3 of the hip's height when the straight legs tilt back).
- **Box position.** The box is a point mass `d_box = 0.114 H + 0.6 L sin(theta_trunk)`
  ahead of the hips in a stoop (against the belly upright, under and a little behind
  the shoulders when bent). In a squat the box must clear the knees, which lie ahead
  of the hips by `l_thigh sin(phi_thigh)` (thigh inclination = hip flexion - trunk
  inclination); the box centre is then taken 0.20 m ahead of the knee (half a 0.3 m
  box plus the knee's own depth; the paper gives no box size, so this is assumed).

Not modelled: the legs' own inertia and weight (a straight prop leg's weight passes
near its hip), knee and ankle moments, vertical accelerations of the upper body,
out-of-plane moments. The non-box leg's moment is therefore a small, bounded
remainder rather than zero: it is nonzero only while the load is still between the
hips *and* the hip has moved back past the turned foot's edge.

Walking and stairs use normative curves (Nm/kg) read from Winter and Schwartz et al.
2008 (walking) and Riener et al. 2002 / Costigan et al. 2002 (stairs), scaled by body
mass and a per-participant factor; the planar model does not apply to them.
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
    """Segment parameters of one wearer (Winter's proportions; see the module docstring)."""

    mass_kg: float
    height_m: float
    m_hat: float
    trunk_length: float  # hip to shoulder
    r_com: float  # hip to HAT centre of mass
    i_hip: float  # HAT moment of inertia about the hip axis
    thigh_length: float = 0.0  # hip to knee
    hip_spacing: float = 0.0  # between the hip joint centres
    stance_width: float = 0.0  # between the feet's centre lines (shoulder width)
    foot_width: float = 0.0
    m_legs_tilt: float = 0.0  # leg mass that moves back with the hips, 0.8 thighs + 0.3 shanks

    @classmethod
    def from_body(cls, mass_kg: float, height_m: float) -> Anthropometrics:
        """Winter's proportions for a body of this mass and height."""
        if mass_kg <= 0 or height_m <= 0:
            raise ValueError("mass and height must be positive")
        m_hat = 0.678 * mass_kg
        length = (0.818 - 0.530) * height_m
        r = 0.626 * length
        rho = 0.496 * length
        return cls(
            mass_kg, height_m, m_hat, length, r, m_hat * (rho * rho + r * r),
            thigh_length=(0.530 - 0.285) * height_m,
            hip_spacing=0.10 * height_m,
            stance_width=0.259 * height_m,
            foot_width=0.055 * height_m,
            m_legs_tilt=(0.8 * 2 * 0.100 + 0.3 * 2 * 0.0465) * mass_kg,
        )

    def box_distance(self, trunk: FloatArray) -> FloatArray:
        """Horizontal hip-to-box distance (m) in a stoop at trunk inclination `trunk`."""
        return 0.114 * self.height_m + 0.6 * self.trunk_length * np.sin(trunk)

    def squat_box_distance(self, trunk: FloatArray, hip_flexion: FloatArray) -> FloatArray:
        """Hip-to-box distance (m) in a squat: as in a stoop, but clear of the knees."""
        thigh = np.clip(np.asarray(hip_flexion) - np.asarray(trunk), 0.0, np.pi / 2)
        knees = self.thigh_length * np.sin(thigh) + SQUAT_BOX_AHEAD_OF_KNEE_M
        return np.maximum(self.box_distance(trunk), knees)


#: Box centre ahead of the knee joint in a squat (m): half a 0.3 m box plus the
#: knee's depth. The paper gives no box size; this is an assumption.
SQUAT_BOX_AHEAD_OF_KNEE_M = 0.20


def _box_distance(
    body: Anthropometrics, trunk: FloatArray, box_distance: FloatArray | None
) -> FloatArray:
    return body.box_distance(trunk) if box_distance is None else np.asarray(box_distance)


def lift_hip_moment(
    body: Anthropometrics, trunk: FloatArray, box_kg: FloatArray, dt: float,
    box_distance: FloatArray | None = None,
) -> FloatArray:
    """Total hip extension moment of both hips (Nm) from the planar model.

    `trunk` (rad) and `box_kg` are sampled every `dt` seconds; the trunk must be smooth
    because its second derivative is taken numerically. `box_distance` (m) overrides
    the stoop's box position (a squat passes `squat_box_distance`).
    """
    trunk = np.asarray(trunk, dtype=np.float64)
    box = np.asarray(box_kg, dtype=np.float64)
    d_box = _box_distance(body, trunk, box_distance)
    acc = np.gradient(np.gradient(trunk, dt), dt) if trunk.size > 2 else np.zeros_like(trunk)
    inertia = body.i_hip + box * d_box * d_box
    static = G * (body.m_hat * body.r_com * np.sin(trunk) + box * d_box)
    return np.asarray(static - inertia * acc, dtype=np.float64)


def stoop_leg_moments(
    body: Anthropometrics, trunk: FloatArray, box_kg: FloatArray, dt: float,
    box_side: int, reach_m: float,
) -> FloatArray:
    """Per-leg moments (K, 2) of an asymmetric stoop towards a box in front of the
    `box_side` foot (0 left, 1 right) standing `reach_m` ahead of the hips.

    The non-box leg carries its hip's vertical load times the lever arm left between
    its turned foot and the hip that moved back; the box-side leg the rest (module
    docstring). Both add up to `lift_hip_moment`.
    """
    if box_side not in (0, 1):
        raise ValueError(f"box_side must be 0 (left) or 1 (right), got {box_side}")
    if reach_m <= 0:
        raise ValueError(f"the box must stand ahead of the hips, got reach {reach_m} m")
    trunk = np.asarray(trunk, dtype=np.float64)
    box = np.asarray(box_kg, dtype=np.float64)
    total = lift_hip_moment(body, trunk, box, dt)
    w_upper = G * (body.m_hat + box)
    static = G * (body.m_hat * body.r_com * np.sin(trunk) + box * body.box_distance(trunk))
    x_u = np.maximum(static / w_upper, 0.0)  # forward lever arm of the upper body's load
    y_u = x_u * (0.5 * body.stance_width) / reach_m  # its shift towards the box side
    load = w_upper * np.clip(0.5 - y_u / body.hip_spacing, 0.0, 1.0)
    back = w_upper * x_u / (w_upper + G * body.m_legs_tilt)  # hips behind the ankles
    lever = np.maximum(back - 0.5 * body.foot_width, 0.0)
    other = load * lever
    out = np.empty((trunk.size, 2))
    out[:, 1 - box_side] = other
    out[:, box_side] = total - other
    return out


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

