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
  the shoulders when bent). In a squat it must also clear the knees: its centre is at
  least 0.20 m ahead of the knee joint (half a 0.3 m box plus the knee's own depth; the
  paper gives no box size, so this is assumed).

**Squat: a moving chain** (`squat_pose`, `top_down_hip_moment`). A squat lift is not
a stoop with an upright back. The hips go down and back, and the thorax leans by the
pelvis' tilt *plus* the lumbar spine's flexion, which a rigid "trunk = pelvis" leaves
out. The chain, ankle to shoulder, from the exoskeleton's hip flexion `phi_hip`:
- pelvis tilt `r_p phi_hip` (the participant's `squat_pelvis_ratio`, 0.36-0.48) and thigh
  inclination `(1 - r_p) phi_hip`; lumbar flexion growing with hip flexion to 25.1 deg
  at the bottom (von Arx et al. 2021: lumbar range of motion in squat lifting of a
  15 kg box, 25.1 +- 8.2 deg, 30 adults), so `theta_trunk = r_p phi_hip + lumbar`;
- shank length 0.246 H (knee height 0.285 H less ankle height 0.039 H, Winter); the
  shank's inclination follows from balance: the centre of mass of shanks (0.567 of the
  knee's forward travel), thighs (centre 0.433 of the thigh below the hip), HAT and the
  held box stays above the ankles, which puts the knee in closed form (feet left out);
- the hands keep the bottom's distance below the shoulders while they carry the box,
  and the box stands on the floor with its grip 0.25 m up (an assumption, the paper
  gives no box size).
The moment about both hips is then Newton-Euler about the moving hip joint centre:
`M = sum_i m_i (x_i (g + z_i'') - z_i x_i'') - I_c theta_trunk''` over the HAT and the
box, each at its position relative to the hip and with its own acceleration (x'', z'')
in the ground frame; `I_c` is the HAT's moment of inertia about its centre of mass.
With the hip held still this is the formula above. Of the two additions, the lumbar
flexion matters: it takes the squat's peak from about 1.2 to about 1.65 Nm/kg per hip
(10 kg box, 75 kg, 1.75 m); the hips' vertical acceleration adds about 0.03. The squat
then peaks about 1-3 % above the stoop's total per hip, the order Van der Have et al.
2019 (the paper's data source) report; the margin is small, so the order rests on the
lumbar flexion measured by von Arx et al. No lifting moments were found to check the
magnitudes against (`tests/fixtures/README.md`).

Not modelled: the legs' own inertia and weight (a straight prop leg's weight passes
near its hip), knee and ankle moments, out-of-plane moments, the stoop's hip travel
(its accelerations are small against g) and the stoop's own lumbar flexion (its trunk
rule is the fixed ratio of `controller.sim.activities`). The non-box leg's moment is
therefore a small, bounded remainder rather than zero: it is nonzero only while the
load is still between the hips *and* the hip has moved back past the turned foot's
edge.

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
    shank_length: float = 0.0  # ankle to knee
    ankle_height: float = 0.0
    m_thighs: float = 0.0  # both thighs
    m_shanks: float = 0.0  # both shanks

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
            shank_length=(0.285 - 0.039) * height_m,
            ankle_height=0.039 * height_m,
            m_thighs=2 * 0.100 * mass_kg,
            m_shanks=2 * 0.0465 * mass_kg,
        )

    def box_distance(self, trunk: FloatArray) -> FloatArray:
        """Horizontal hip-to-box distance (m) in a stoop at trunk inclination `trunk`."""
        return 0.114 * self.height_m + 0.6 * self.trunk_length * np.sin(trunk)


#: Box centre ahead of the knee joint in a squat (m): half a 0.3 m box plus the
#: knee's depth. The paper gives no box size; this is an assumption.
SQUAT_BOX_AHEAD_OF_KNEE_M = 0.20


def lift_hip_moment(
    body: Anthropometrics, trunk: FloatArray, box_kg: FloatArray, dt: float
) -> FloatArray:
    """Total hip extension moment of both hips (Nm) about hips that stay in place:
    standing, and the stoop, whose hips move back as the straight legs tilt but with
    accelerations small against g (under about 1 m/s^2; `top_down_hip_moment` for
    hips that move, as in a squat).

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


#: Lumbar flexion at the bottom of a squat lift (deg): the lumbar range of motion
#: von Arx et al. 2021 measured in squat lifting of a 15 kg box from the floor
#: (25.1 +- 8.2 deg, 30 adults). The thorax inclines by the pelvis' tilt plus this.
SQUAT_LUMBAR_FLEXION_DEG = 25.1

#: Height of the hands above the floor as they take the box (m): a box standing on the
#: floor, held by handles near its top. The paper gives no box size: an assumption.
GRIP_HEIGHT_M = 0.25


@dataclass(frozen=True, slots=True)
class SquatPose:
    """The sagittal chain of a squat lift over time (x forward of the ankles, z up, m)."""

    trunk: FloatArray  # thorax inclination from vertical (rad)
    thigh: FloatArray  # thigh inclination from vertical, knee ahead of the hip (rad)
    knee_x: FloatArray
    hip: FloatArray  # (K, 2) hip joint centre
    box: FloatArray  # (K, 2) box centre (where the hands hold it)


def _squat_chain(
    body: Anthropometrics, flexion: FloatArray, thigh: FloatArray, lumbar: FloatArray,
    box_kg: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Trunk, knee x, hip (x, z), shoulder height and box x for a squat posture, with
    the whole body's centre of mass above the ankles (feet flat, quasi-static balance).

    Every segment above the knee sits at a fixed offset from it, and the shank's centre
    of mass at 0.567 of the knee's forward travel (Winter: 0.433 of the shank from the
    knee), so balance gives the knee's position in closed form. The feet are left out.
    """
    trunk = flexion - thigh + lumbar
    off_hip = -body.thigh_length * np.sin(thigh)
    off_thigh = 0.567 * off_hip  # thigh centre of mass 0.433 of its length below the hip
    off_hat = off_hip + body.r_com * np.sin(trunk)
    off_box = np.maximum(SQUAT_BOX_AHEAD_OF_KNEE_M, off_hip + body.box_distance(trunk))
    moment = body.m_thighs * off_thigh + body.m_hat * off_hat + box_kg * off_box
    knee_x = -moment / (body.m_hat + body.m_thighs + box_kg + 0.567 * body.m_shanks)
    shank = np.arcsin(np.clip(knee_x / body.shank_length, -1.0, 1.0))
    hip_x = knee_x + off_hip
    hip_z = body.ankle_height + body.shank_length * np.cos(shank) + body.thigh_length * np.cos(
        thigh
    )
    shoulder_z = hip_z + body.trunk_length * np.cos(trunk)
    return trunk, knee_x, np.stack([hip_x, hip_z], axis=-1), shoulder_z, knee_x + off_box


def squat_pose(
    body: Anthropometrics, flexion: FloatArray, pelvis_ratio: float, box_kg: FloatArray,
    lumbar_deg: float = SQUAT_LUMBAR_FLEXION_DEG,
) -> SquatPose:
    """The chain of a squat lift from the mean hip flexion above standing (rad).

    The pelvis tilts by `pelvis_ratio` of the hip flexion and the thigh by the rest;
    the lumbar spine flexes in proportion to hip flexion up to `lumbar_deg` at the
    bottom, so the thorax inclines by the pelvis' tilt plus that flexion. The hands
    keep the bottom's distance below the shoulders while they hold the box.
    """
    flexion = np.asarray(flexion, dtype=np.float64)
    box = np.asarray(box_kg, dtype=np.float64)
    peak = float(flexion.max())
    if peak <= 0.0:
        raise ValueError("a squat needs hip flexion")
    if not 0.0 <= pelvis_ratio < 1.0:
        raise ValueError(f"pelvis_ratio must be in [0, 1), got {pelvis_ratio}")
    q = np.clip(flexion / peak, 0.0, 1.0)
    thigh = (1.0 - pelvis_ratio) * flexion
    lumbar = np.radians(lumbar_deg) * q
    trunk, knee_x, hip, shoulder_z, box_x = _squat_chain(body, flexion, thigh, lumbar, box)
    drop = float(shoulder_z[int(np.argmax(flexion))]) - GRIP_HEIGHT_M
    box_xz = np.stack([box_x, shoulder_z - drop], axis=-1)
    return SquatPose(trunk, thigh, knee_x, hip, box_xz)


def top_down_hip_moment(
    body: Anthropometrics, trunk: FloatArray, hip: FloatArray, box: FloatArray,
    box_kg: FloatArray, dt: float,
) -> FloatArray:
    """Total hip extension moment of both hips (Nm) when the hips themselves move.

    Newton-Euler for the upper body about the moving hip joint centre: each mass m at
    (x, z) relative to the hip needs m (x (g + z'') - z x''), with its own acceleration
    (x'', z'') in the ground frame; the HAT adds its rotation about its own centre of
    mass, I_c theta''. With a fixed hip and no box this is `lift_hip_moment`.
    """
    trunk = np.asarray(trunk, dtype=np.float64)
    w = np.asarray(box_kg, dtype=np.float64)
    com = hip + body.r_com * np.stack([np.sin(trunk), np.cos(trunk)], axis=-1)

    def acc(x: FloatArray) -> FloatArray:
        return np.asarray(np.gradient(np.gradient(x, dt, axis=0), dt, axis=0))

    def lever(m: FloatArray | float, at: FloatArray) -> FloatArray:
        a = acc(at)
        rel = at - hip
        return np.asarray(m * (rel[:, 0] * (G + a[:, 1]) - rel[:, 1] * a[:, 0]))

    i_com = body.i_hip - body.m_hat * body.r_com**2
    spin = i_com * np.gradient(np.gradient(trunk, dt), dt)
    return np.asarray(lever(body.m_hat, com) + lever(w, box) - spin, dtype=np.float64)


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

