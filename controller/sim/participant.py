"""Virtual participants: the body and habits of one simulated wearer, drawn from a seed.

Everything a participant does differently from another (size, speed, depth, favouring
one leg, how consistent they are, how the exoskeleton sits on them) is fixed here, so
that a seed names a person and the same seed always gives the same person. The
activity generators add repetition-to-repetition variation on top of these means.

Distributions are the project's own assumptions, chosen to cover the spreads reported
in `docs/simulated-wearer.md` and the paper's cohort (young adults, mostly male).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

SEXES: tuple[str, str] = ("male", "female")

# Sway: three slow sinusoids per hip; frequencies of quiet-standing postural sway.
_SWAY_FREQS_HZ = (0.07, 0.19, 0.41)


def _rng(*key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([0x5E_ED, *key]))


@dataclass(frozen=True)
class VirtualParticipant:
    """One simulated wearer. Angles in degrees where the name says so, else radians.

    Build with `from_seed`; `donned` gives the same person after another donning (a new
    standing offset of the exoskeleton on the body).
    """

    seed: int
    sex: str
    mass_kg: float
    height_m: float
    speed: float  # multiplies every movement speed (1 = nominal)
    squat_depth_deg: float  # mean peak hip flexion in a squat
    stoop_depth_deg: float  # mean peak hip flexion of the box-side hip in a stoop
    stoop_other_ratio: float  # other hip's peak flexion over the box-side hip's, in a stoop
    squat_pelvis_ratio: float  # pelvis tilt over hip flexion in a squat (lumbar flexion adds)
    asymmetry: float  # left over right flexion ratio minus 1 (favours a leg)
    rep_variation: float  # relative SD of depth and duration between repetitions
    stand_flexion_deg: tuple[float, float]  # true hip flexion when standing, left/right
    walk_range_deg: float  # hip flexion range in level walking
    stride_s: float  # walking stride duration
    stair_stride_s: float  # stair ascent stride duration (descent is 10 % quicker)
    torque_scale: float  # gait and stair moments relative to the normative curves
    sway_deg: float  # amplitude of quiet-standing sway at the hip
    sway_phases: tuple[float, ...]  # 3 per hip, left then right
    donning: int  # which donning of the exoskeleton the offsets belong to
    offset_deg: tuple[float, float]  # exoskeleton standing offset per hip for this donning
    drift_deg: tuple[float, float]  # amplitude of the slow offset drift per hip
    drift_period_s: tuple[float, float]
    drift_phase: tuple[float, float]

    def __post_init__(self) -> None:
        if self.sex not in SEXES:
            raise ValueError(f"sex must be one of {SEXES}, got {self.sex!r}")
        if not (40.0 <= self.mass_kg <= 150.0 and 1.4 <= self.height_m <= 2.1):
            raise ValueError(f"implausible body: {self.mass_kg} kg, {self.height_m} m")
        if len(self.sway_phases) != 6:
            raise ValueError("sway_phases needs 3 phases per hip")

    @classmethod
    def from_seed(cls, seed: int, donning: int = 0) -> VirtualParticipant:
        """The participant named by `seed` (deterministic across runs and machines)."""
        if seed < 0:
            raise ValueError(f"participant seed must be non-negative, got {seed}")
        r = _rng(int(seed), 1)
        # The paper's evaluation cohort was 7 of 8 male; keep a similar mix.
        sex = "female" if r.random() < 0.2 else "male"
        if sex == "male":
            height = float(np.clip(r.normal(1.79, 0.07), 1.62, 1.98))
            bmi = float(np.clip(r.normal(24.0, 2.5), 19.0, 31.0))
        else:
            height = float(np.clip(r.normal(1.67, 0.06), 1.52, 1.82))
            bmi = float(np.clip(r.normal(22.5, 2.5), 18.5, 30.0))
        mass = bmi * height * height
        asym = float(np.clip(r.normal(0.0, 0.025), -0.06, 0.06))
        stand = r.uniform(1.0, 6.0)
        stand_l = float(stand + r.normal(0.0, 0.8))
        stand_r = float(stand + r.normal(0.0, 0.8))
        base = cls(
            seed=int(seed),
            sex=sex,
            mass_kg=round(mass, 2),
            height_m=round(height, 3),
            speed=float(np.clip(r.normal(1.0, 0.1), 0.8, 1.25)),
            squat_depth_deg=float(r.uniform(92.0, 108.0)),
            stoop_depth_deg=float(r.uniform(76.0, 94.0)),
            stoop_other_ratio=float(r.uniform(0.62, 0.78)),
            squat_pelvis_ratio=float(r.uniform(0.36, 0.48)),
            asymmetry=asym,
            rep_variation=float(r.uniform(0.03, 0.07)),
            stand_flexion_deg=(stand_l, stand_r),
            walk_range_deg=float(r.uniform(36.0, 46.0)),
            stride_s=float(r.uniform(1.0, 1.2)),
            stair_stride_s=float(r.uniform(1.3, 1.6)),
            torque_scale=float(r.uniform(0.88, 1.12)),
            sway_deg=float(r.uniform(0.15, 0.45)),
            sway_phases=tuple(float(x) for x in r.uniform(0.0, 2.0 * math.pi, 6)),
            donning=0,
            offset_deg=(0.0, 0.0),
            drift_deg=(0.0, 0.0),
            drift_period_s=(300.0, 300.0),
            drift_phase=(0.0, 0.0),
        )
        return base.donned(donning)

    def donned(self, donning: int) -> VirtualParticipant:
        """The same person after donning number `donning`: a new standing offset of each
        hip encoder and a new slow drift (the straps settle during use).

        Offsets are normal with a 3 degree SD, clipped at 7 degrees: "several degrees",
        so about one hip in three is off by more than 3 degrees (half the wearers have one),
        as the paper's participants 3 and 7 evidently had (their UMC failed, the
        E-UMC's calibration fixed it). Drift: 0.3-1.2 degrees over a 2.5-10 minute
        period. Both are assumptions (no measurement of this exoskeleton's fit is
        published); `docs/simulated-wearer.md`."""
        r = _rng(self.seed, 2, int(donning))
        off = np.clip(r.normal(0.0, 3.0, 2), -7.0, 7.0)
        drift = r.uniform(0.3, 1.2, 2)
        period = r.uniform(150.0, 600.0, 2)
        phase = r.uniform(0.0, 2.0 * math.pi, 2)
        return replace(
            self,
            donning=int(donning),
            offset_deg=(float(off[0]), float(off[1])),
            drift_deg=(float(drift[0]), float(drift[1])),
            drift_period_s=(float(period[0]), float(period[1])),
            drift_phase=(float(phase[0]), float(phase[1])),
        )

    @property
    def stand_flexion(self) -> np.ndarray:
        """True standing hip flexion (rad), shape (2,)."""
        return np.radians(np.asarray(self.stand_flexion_deg))

    def sway(self, t: np.ndarray) -> np.ndarray:
        """Quiet-standing sway (rad), shape (len(t), 2): a smooth function of absolute
        time, so that concatenated segments and looped scripts stay continuous."""
        t = np.asarray(t, dtype=np.float64)
        out = np.zeros((t.size, 2))
        amp = math.radians(self.sway_deg) / len(_SWAY_FREQS_HZ)
        for leg in range(2):
            for i, f in enumerate(_SWAY_FREQS_HZ):
                ph = self.sway_phases[3 * leg + i]
                out[:, leg] += amp * np.sin(2.0 * math.pi * f * t + ph)
        return out

    def encoder_offset(self, t: np.ndarray) -> np.ndarray:
        """Exoskeleton link angle minus true hip flexion (rad), shape (len(t), 2): the
        donning offset plus a slow bounded drift that is zero at t = 0."""
        t = np.asarray(t, dtype=np.float64)
        out = np.empty((t.size, 2))
        for leg in range(2):
            ph = self.drift_phase[leg]
            w = 2.0 * math.pi / self.drift_period_s[leg]
            drift = self.drift_deg[leg] * (np.sin(w * t + ph) - math.sin(ph))
            out[:, leg] = np.radians(self.offset_deg[leg] + drift)
        return out
