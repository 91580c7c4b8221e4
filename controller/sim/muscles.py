"""Muscle activation of the simulated wearer, from the moments the simulation computes.

Why: the study's main physiological outcome is how much the exoskeleton lowers back and
hip extensor activity. A virtual participant therefore needs muscles whose activity
follows the moment they must supply *after* the exoskeleton's springs have supplied
theirs, so that the whole EMG chain can be checked against a known truth.

The model, per tick (arrays of any length; 1 = maximum voluntary activation):

- **Net moments.** Hip, per leg `s`: `H_s = M_s - T_s` (the wearer's hip extension
  moment from `controller.sim.biomechanics` minus the exoskeleton's extension torque on
  that side). Lumbar (L5/S1), for the whole trunk: `L = k (M_l + M_r - T_l - T_r)`, with
  `k = LUMBAR_TO_HIP` (assumed 0.8): the moment about L5/S1 is smaller than about the
  hips because L5/S1 lies above them, nearer the upper body's load; the same ratio is
  applied to the exoskeleton's torque, whose reaction acts on the trunk through its
  chest pad (an assumption: the load and the pad are taken to have the same ratio of
  lever arms about the two axes). The erector spinae of both sides share `L` equally
  (sagittal model: the twisting and side-bending of an asymmetric lift are not modelled).
- **Recruitment.** Within a joint the synergists take fixed shares of the net extension
  moment, equal to their shares of the joint's nominal strength (`SHARES`), so that at
  nominal strength every synergist works at the same fraction of its maximum (the
  min/max recruitment criterion, Rasmussen, Damsgaard and Voigt 2001, J Biomech
  34(3):409-415). A participant's muscles differ from nominal by a seeded strength
  factor per muscle and side, so the same share costs a weaker muscle more activation.
- **Activation** `a = b + (1 - b) clip(share x demand / (share x maximum), 0, 1)`: `b`
  is the muscle's tonic (baseline) activity, `BASELINE`; with the exoskeleton's torque
  equal to the required moment, the agonists drop to exactly `b`.
- **Antagonists.** Rectus abdominis (trunk flexor) and rectus femoris (hip flexor):
  baseline, plus a co-contraction proportional to the extensors' activity on that side
  (`CO_CONTRACTION`, an assumption), plus any net *flexion* demand (the net moment
  negative: walking's toe-off, or springs that give more than is needed) over the
  flexors' maximum.

Maximum moments scale with body mass (Nm/kg), as the simulation's moments do, with a
factor for women (`FEMALE_PER_KG`) and a seeded per-participant and per-muscle factor.
Sources and the status of every number: `docs/muscle-activity.md`.

Not modelled: activation dynamics and the electromechanical delay (EMG leads force by
tens of ms), the flexion-relaxation of the back extensors in full flexion (passive
tissues take over; the model overestimates back activity at the very bottom of a deep
stoop), knee moments (the hamstrings also flex the knee), length and velocity effects.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.sim.participant import VirtualParticipant

FloatArray = NDArray[np.float64]

#: Muscle ids, as everywhere in the project (montage, outcomes, exports).
MUSCLES: tuple[str, ...] = (
    "erector_spinae_lumbar",
    "erector_spinae_thoracic",
    "gluteus_maximus",
    "biceps_femoris",
    "rectus_abdominis",
    "rectus_femoris",
)
SIDES: tuple[str, str] = ("left", "right")
#: The 12 channels (muscle, side) in a fixed order: all muscles left, then right.
CHANNELS: tuple[tuple[str, str], ...] = tuple((m, s) for s in SIDES for m in MUSCLES)

#: Which moment each muscle answers: lumbar extension, hip extension, or a flexor.
JOINT: dict[str, str] = {
    "erector_spinae_lumbar": "lumbar_extension",
    "erector_spinae_thoracic": "lumbar_extension",
    "gluteus_maximus": "hip_extension",
    "biceps_femoris": "hip_extension",
    "rectus_abdominis": "lumbar_flexion",
    "rectus_femoris": "hip_flexion",
}

#: Maximum voluntary isometric moments of healthy young men (Nm per kg body mass).
#: Trunk extension about L5/S1, both sides together: 3.3 Nm/kg, about 250 Nm at 76 kg,
#: inside the 200-300 Nm range dynamometry reports for healthy men (docs).
#: Hip extension per leg: 3.0 Nm/kg (about 230 Nm at 76 kg). Flexors: hip flexion per
#: leg 2.0 Nm/kg and trunk flexion 2.2 Nm/kg, below the extensors as dynamometry
#: consistently finds (assumed values; only their flexion-demand term uses them).
MAX_NM_PER_KG: dict[str, float] = {
    "lumbar_extension": 3.3,
    "hip_extension": 3.0,
    "hip_flexion": 2.0,
    "lumbar_flexion": 2.2,
}
#: Women's maxima per kg body mass relative to men's: absolute trunk strength of women
#: is 60-70 % of men's (Kumar, Dufresne and Van Schoor 1995, Spine 20(2):160-168) with
#: about 80 % of their body mass, so about 0.8 per kg (the same factor for the hip).
FEMALE_PER_KG = 0.8
#: Moment about L5/S1 over the moment about both hips (assumption, module docstring).
LUMBAR_TO_HIP = 0.8
#: Part of a net flexion demand the flexor muscles supply actively (assumed 0.5): in
#: late stance, where walking's hip flexion moment peaks, the hip is extended and its
#: anterior ligaments and stretched flexors carry much of that moment passively.
ACTIVE_FLEXION = 0.5

#: Each muscle's share of its joint's moment. Hip: gluteus maximus and the hamstrings by
#: physiological cross-sectional area (Ward et al. 2009, Clin Orthop Relat Res
#: 467(4):1074-1082: gluteus maximus 33.8 cm^2; semimembranosus 18.4, semitendinosus 4.9,
#: biceps femoris long head 11.3, together 34.6 cm^2), equal moment arms assumed; the
#: biceps femoris channel stands for the hamstrings. Trunk: the lumbar and thoracic parts
#: of the erector spinae, 0.5 each of the erector spinae's part (assumed; with the
#: recruitment rule above the split changes moments per muscle, not activation).
SHARES: dict[str, float] = {
    "erector_spinae_lumbar": 0.5,
    "erector_spinae_thoracic": 0.5,
    "gluteus_maximus": 33.8 / (33.8 + 34.6),
    "biceps_femoris": 34.6 / (33.8 + 34.6),
    "rectus_abdominis": 1.0,
    "rectus_femoris": 1.0,
}

#: Tonic activity in quiet standing, fraction of maximum (assumed: a few % of MVC).
BASELINE: dict[str, float] = {
    "erector_spinae_lumbar": 0.02,
    "erector_spinae_thoracic": 0.02,
    "gluteus_maximus": 0.01,
    "biceps_femoris": 0.01,
    "rectus_abdominis": 0.015,
    "rectus_femoris": 0.01,
}
#: Antagonist co-contraction per unit of agonist activation above baseline (assumed).
CO_CONTRACTION: dict[str, float] = {"rectus_abdominis": 0.08, "rectus_femoris": 0.05}
#: The agonist whose activity drives each antagonist's co-contraction.
_AGONIST = {"rectus_abdominis": "erector_spinae_lumbar", "rectus_femoris": "gluteus_maximus"}

#: Per-participant strength spread: a person factor and a muscle factor (log-normal SDs).
PERSON_STRENGTH_SD = 0.15
MUSCLE_STRENGTH_SD = 0.08


@dataclass(frozen=True)
class MuscleModel:
    """The maxima of one participant's muscles and how activation follows from moments.

    `max_nm[(muscle, side)]` is that muscle's maximum moment about its joint (Nm), its
    share of the joint's maximum included. Build with `for_participant`.
    """

    mass_kg: float
    max_nm: dict[tuple[str, str], float]

    @classmethod
    def for_participant(cls, participant: VirtualParticipant) -> MuscleModel:
        """Maxima for this participant: Nm/kg x body mass x sex factor x seeded factors."""
        return cls.from_body(participant.mass_kg, participant.sex, participant.seed)

    @classmethod
    def from_body(cls, mass_kg: float, sex: str = "male", seed: int | None = None) -> MuscleModel:
        """Maxima for a body; `seed` None gives nominal strength (no individual factors)."""
        if mass_kg <= 0:
            raise ValueError(f"body mass must be positive, got {mass_kg}")
        per_kg = 1.0 if sex == "male" else FEMALE_PER_KG
        if seed is None:
            factors = np.ones(len(CHANNELS))
        else:
            r = np.random.default_rng(np.random.SeedSequence([0x3A_5C1E, int(seed)]))
            person = r.normal(0.0, PERSON_STRENGTH_SD)
            factors = np.exp(person + r.normal(0.0, MUSCLE_STRENGTH_SD, len(CHANNELS)))
        # The trunk's maxima are for both sides together; each side has half.
        sides = {"lumbar_extension": 0.5, "lumbar_flexion": 0.5}
        max_nm = {
            ch: float(MAX_NM_PER_KG[JOINT[ch[0]]] * sides.get(JOINT[ch[0]], 1.0)
                      * SHARES[ch[0]] * mass_kg * per_kg * f)
            for ch, f in zip(CHANNELS, factors, strict=True)
        }
        return cls(float(mass_kg), max_nm)

    def activation(self, human_nm: ArrayLike, exo_nm: ArrayLike) -> FloatArray:
        """Activation (K, 12) in `CHANNELS` order from the wearer's hip extension moments
        and the exoskeleton's extension torques, both (K, 2) Nm (left, right) or (2,)."""
        m = np.atleast_2d(np.asarray(human_nm, dtype=np.float64))
        t = np.atleast_2d(np.asarray(exo_nm, dtype=np.float64))
        if m.shape[-1] != 2 or t.shape != m.shape:
            raise ValueError(f"moments and torques must both be (K, 2), got {m.shape}, {t.shape}")
        hip = m - t  # (K, 2) net hip extension demand per leg
        lumbar = LUMBAR_TO_HIP * hip.sum(axis=1)  # (K,) net about L5/S1, whole trunk
        out = np.empty((m.shape[0], len(CHANNELS)))
        col = {ch: i for i, ch in enumerate(CHANNELS)}
        for s, side in enumerate(SIDES):
            demand = {
                "lumbar_extension": np.maximum(0.5 * lumbar, 0.0),
                "hip_extension": np.maximum(hip[:, s], 0.0),
                "lumbar_flexion": ACTIVE_FLEXION * np.maximum(-0.5 * lumbar, 0.0),
                "hip_flexion": ACTIVE_FLEXION * np.maximum(-hip[:, s], 0.0),
            }
            for muscle in MUSCLES:
                # share x demand over share x maximum: the muscle's own maximum holds
                # its share already (`max_nm`), so the demand takes it here.
                need = SHARES[muscle] * demand[JOINT[muscle]] / self.max_nm[(muscle, side)]
                out[:, col[(muscle, side)]] = np.clip(need, 0.0, 1.0)
            for muscle, agonist in _AGONIST.items():
                c = col[(muscle, side)]
                out[:, c] = np.clip(
                    out[:, c] + CO_CONTRACTION[muscle] * out[:, col[(agonist, side)]], 0.0, 1.0
                )
        base = np.array([BASELINE[mu] for mu, _ in CHANNELS])
        return np.asarray(base + (1.0 - base) * out, dtype=np.float64)

    def tick_activation(self, human_nm: Sequence[float],
                        exo_nm: Sequence[float]) -> list[float]:
        """One tick's activation: `activation(human_nm, exo_nm)[0]` as 12 Python floats,
        from (left, right) moments and torques. The same operations in the same order,
        so the same values; a tick of the simulated amplifier would otherwise spend most
        of its time in numpy's per-call overhead on arrays of two and twelve values.
        (`0.0 if v < 0.0 else v` keeps a NaN, as np.maximum and np.clip do.)"""
        hip_l = float(human_nm[0]) - float(exo_nm[0])
        hip_r = float(human_nm[1]) - float(exo_nm[1])
        net = (0.5 * (LUMBAR_TO_HIP * (hip_l + hip_r)), hip_l, hip_r)
        # Extension demands, then flexion demands, as `_SOURCE` numbers them.
        demand = [0.0 if v < 0.0 else v for v in net]
        demand += [ACTIVE_FLEXION * (0.0 if v > 0.0 else -v) for v in net]
        tab = self._tick
        need = [share * demand[src] / top for src, share, top in tab.need]
        out = [0.0 if v < 0.0 else 1.0 if v > 1.0 else v for v in need]
        for c, agonist, co in tab.co_contraction:
            v = out[c] + co * out[agonist]
            out[c] = 0.0 if v < 0.0 else 1.0 if v > 1.0 else v
        return [base + above * a for (base, above), a in zip(tab.base, out, strict=True)]

    @cached_property
    def _tick(self) -> _Tick:
        """`tick_activation`'s constants per channel, built once per model."""
        return _Tick(
            need=tuple((_SOURCE[(JOINT[m], s)], SHARES[m], self.max_nm[(m, s)])
                       for m, s in CHANNELS),
            co_contraction=tuple(
                (CHANNELS.index((m, s)), CHANNELS.index((a, s)), CO_CONTRACTION[m])
                for s in SIDES for m, a in _AGONIST.items()),
            base=tuple((BASELINE[m], 1.0 - BASELINE[m]) for m, _ in CHANNELS),
        )


class _Tick(NamedTuple):
    """`MuscleModel`'s constants per channel (`CHANNELS` order), for one tick at a time."""

    need: tuple[tuple[int, float, float], ...]  # (demand answered, share, maximum Nm)
    co_contraction: tuple[tuple[int, int, float], ...]  # (antagonist, agonist, factor)
    base: tuple[tuple[float, float], ...]  # (baseline b, 1 - b)


#: Index of each (joint, side)'s demand in `tick_activation`: each side's half of the
#: lumbar extension moment, hip extension left and right, then the flexions alike.
_SOURCE: dict[tuple[str, str], int] = {
    **{("lumbar_extension", s): 0 for s in SIDES},
    ("hip_extension", "left"): 1, ("hip_extension", "right"): 2,
    **{("lumbar_flexion", s): 3 for s in SIDES},
    ("hip_flexion", "left"): 4, ("hip_flexion", "right"): 5,
}


def channel_label(muscle: str, side: str) -> str:
    """The channel's label, `<muscle>_<side>`, as the montage matches it."""
    return f"{muscle}_{side}"
