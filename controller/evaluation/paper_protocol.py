"""The paper's protocol on virtual participants, and the replication's measures beyond the
seeds: pure evaluation, no database, no files.

- `protocol_seed`: one seed of the paper's study (its evaluation participants, the
  data-collection participants whose demonstrations fit its motion models) replayed
  through the controllers with the cohort engine's own trial replay
  (`controller.evaluation.cohort.replay_trial`), the virtual study's seeds and
  participants, no server.
- `measure_seed`: a seed's per-claim numbers (`controller.evaluation.paper_claims`) plus
  its model-set measure.
- `method_checks`, `offset_regression`, `stair_kinematics`: the claims that need no
  seed (utilities, value iteration, chi-square tail, actuator), the donning-offset
  regression over one larger cohort, and the simulated stair kinematics against
  published ranges.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy import stats
from scipy.signal import find_peaks

from controller.config import ControllerConfig
from controller.decision.utility_function import UtilitySet
from controller.evaluation.cohort import (
    CohortConfig,
    default_utilities,
    replay_trial,
    simulate_cohort,
    trial_recording,
)
from controller.evaluation.columns import TickData
from controller.evaluation.method_figures import PRECOMPRESSIONS
from controller.evaluation.paper_claims import seed_measures, trial_data
from controller.evaluation.study import RecordingEvaluation
from controller.evaluation.verdicts import t_interval
from controller.intent.motion_model import ModelSet
from controller.intent.posteriors import likelihood
from controller.lowlevel.actuator import maccepa_torque, max_deflection
from controller.sim.demonstrations import simulated_model_set
from controller.sim.participant import VirtualParticipant
from controller.sim.scripts import get_script, realise
from controller.tick_record import CATEGORY_NAMES, Action

#: One seed's evaluated trials with their ticks.
SeedTrials = list[tuple[TickData, RecordingEvaluation]]
#: The paper's protocol (data about the paper's study, not a property of the
#: controllers): every participant used the UMC and the PEC in this order, the first
#: `eumc` participants also the E-UMC, whose trials the paper's timeline figure shows.
PAPER_CONTROLLERS = ("umc", "pec")
PAPER_EXTRA = "eumc"
#: The precompression of the paper's study (%).
PAPER_PRECOMPRESSION = 25.0
#: Published stair kinematics compared with the simulation (see docs/replication.md).
PUBLISHED_STAIRS: dict[str, dict[str, Any]] = {
    "stairs_up": {"hip_rom_deg": (55.0, 70.0), "cadence_spm": (85.0, 100.0),
                  "source": "Riener et al. 2002 (Gait Posture 15:32-44); Protopapadaki et "
                            "al. 2007 (Clin Biomech 22:203-210)"},
    "stairs_down": {"hip_rom_deg": (25.0, 40.0), "cadence_spm": (90.0, 110.0),
                    "source": "Riener et al. 2002; Protopapadaki et al. 2007"},
}


def protocol_seed(seed: int, participants: int, eumc: int, data_participants: int,
                  utilities: UtilitySet | None = None
                  ) -> tuple[SeedTrials, ModelSet, UtilitySet]:
    """The protocol of one seed replayed through the controllers in this process: the
    virtual study's participants (`seed*100 + 1 + j`) and data-collection seeds
    (`seed*100 + 50 + i`), each controller on its own repetition of the script.
    `utilities`: `default_utilities(PAPER_PRECOMPRESSION)` if the caller already has
    it (it is the same for every seed), else computed here."""
    models = simulated_model_set(seeds=[seed * 100 + 50 + i for i in range(data_participants)])
    if utilities is None:
        utilities = default_utilities(PAPER_PRECOMPRESSION)
    docs = (models.to_json(), utilities.to_json())
    settings = ControllerConfig(precompression_pct=PAPER_PRECOMPRESSION)
    start = models.start_posture()
    out: SeedTrials = []
    for j in range(participants):
        pseed = seed * 100 + 1 + j
        p = VirtualParticipant.from_seed(pseed)
        ctls = [*PAPER_CONTROLLERS, *([PAPER_EXTRA] if j < eumc else [])]
        for i, name in enumerate(ctls):
            rec = trial_recording(p, pseed, "paper-evaluation", repetition=i)
            cols, ev, _tried = replay_trial(rec, name, settings, start, docs, f"P{j + 1:02d}")
            out.append((cols, ev))
    return out, models, utilities


def _online_end(models: ModelSet | None) -> float:
    if models is None:
        return 0.5
    m = models.ordered()[0]
    return (m.online_n - 1) / (m.mean.shape[0] - 1)


def models_separation(models: ModelSet) -> float:
    """Smaller stoop |L - R| minus squat |L - R| (deg) at the end of the online part."""
    by = {m.name: m for m in models.ordered()}
    k = by["squat"].online_n - 1

    def gap(name: str) -> float:
        mu = np.degrees(by[name].mean[k])
        return float(abs(mu[0] - mu[1]))

    return min(gap("stoop_left"), gap("stoop_right")) - gap("squat")


def measure_seed(trials: Sequence[tuple[TickData, RecordingEvaluation]],
                 models: ModelSet | None) -> dict[str, float]:
    """`seed_measures` of one seed plus its model-set measure."""
    end = _online_end(models)
    m = seed_measures([trial_data(c, e, end) for c, e in trials])
    if models is not None:
        m["models_separation_deg"] = models_separation(models)
    return m


def method_checks(utilities: UtilitySet) -> dict[str, float]:
    """The deterministic claims: utilities, value iteration, chi-square, actuator."""
    v = utilities.table.values
    gaps = []
    for kind, other in (("stoop_left", Action.LOCK_RIGHT), ("stoop_right", Action.LOCK_LEFT)):
        j = CATEGORY_NAMES.index(kind)
        gaps.append(float(v[int(Action.NO_LOCK) - 1, j, 0] - v[int(other) - 1, j, 0]))
    gap = utilities.meta.get("assumption_gap", {})
    scale = float(np.abs(v[:, :3]).max()) or 1.0
    vi = max((float(x) for x in gap.values()), default=math.nan) / scale
    # Within each curve's compression limit: torque grows with deflection, and at a
    # deflection every curve reaches, with precompression.
    tops = [max_deflection(p) for p in PRECOMPRESSIONS]
    bad = n = 0
    for p, top in zip(PRECOMPRESSIONS, tops, strict=True):
        tau = np.asarray(maccepa_torque(np.linspace(0.0, top, 60), p), dtype=np.float64)
        bad += int((np.diff(tau) < -1e-12).sum())
        n += tau.size - 1
    usable = [p for p, top in zip(PRECOMPRESSIONS, tops, strict=True) if top > 0]
    common = np.linspace(0.0, min(t for t in tops if t > 0), 60)
    curves = np.array([np.asarray(maccepa_torque(common, p), dtype=np.float64)
                       for p in usable])
    bad += int((np.diff(curves, axis=0) < -1e-12).sum())
    n += curves.shape[1] * (curves.shape[0] - 1)
    return {"utility_stoop_gap": min(gaps), "value_iteration_gap": vi,
            "chi_square_tail": float(likelihood(7.5, 3)), "actuator_violations": bad / n}


def offset_regression(participants: int, seed: int, log: Callable[[str], None],
                      utilities: UtilitySet | None = None) -> dict[str, Any]:
    """UMC minus E-UMC correct decisions (per 20 lifts, the paper's counting rule)
    against the donning offset, over a virtual cohort; ordinary least squares.
    `utilities`: `default_utilities(PAPER_PRECOMPRESSION)` if the caller already has
    it, else the cohort computes it."""
    ccfg = CohortConfig(participants=participants, seed=seed, controllers=("umc", "eumc"),
                        precompression_pct=PAPER_PRECOMPRESSION)
    log(f"offsets: simulating a cohort of {ccfg.participants}")
    cohort = simulate_cohort(ccfg, utilities=utilities)
    off = np.array([p.body["offset_deg"] for p in cohort.participants], dtype=np.float64)
    gain = (cohort.values("umc", "correct_pct") - cohort.values("eumc", "correct_pct")) / 5.0
    out: dict[str, Any] = {"participants": ccfg.participants, "seed": ccfg.seed,
                           "offset_deg": off.tolist(), "gain": gain.tolist()}
    iv = t_interval(gain)
    out["mean_gain"] = {"mean": iv.mean, "low": iv.low, "high": iv.high}
    for name, x in (("both", np.abs(off).mean(axis=1)),
                    ("difference", np.abs(off[:, 0] - off[:, 1]))):
        ok = np.isfinite(x) & np.isfinite(gain)
        fit = stats.linregress(x[ok], gain[ok])
        tcrit = float(stats.t.ppf(0.975, int(ok.sum()) - 2))
        out[name] = {"slope": float(fit.slope), "intercept": float(fit.intercept),
                     "stderr": float(fit.stderr), "low": float(fit.slope - tcrit * fit.stderr),
                     "high": float(fit.slope + tcrit * fit.stderr), "r": float(fit.rvalue),
                     "p": float(fit.pvalue), "n": int(ok.sum()), "x": x[ok].tolist()}
    return out


def stair_kinematics(n: int, first_seed: int = 1) -> dict[str, Any]:
    """Hip flexion range, peak, cadence and leg asymmetry of the simulated stair ascent
    and descent, per participant, from the `stairs` script (steady strides only: the
    0.8 s cross-fades at the ends of each piece are left out)."""
    script = get_script("stairs")
    res: dict[str, dict[str, list[float]]] = {}
    cycles: dict[str, list[np.ndarray]] = {}
    for j in range(n):
        seed = 2_000_000 + first_seed * 1000 + j
        p = VirtualParticipant.from_seed(seed)
        tr = realise(script, p, seed)
        act = tr.activity_names()
        deg = np.degrees(tr.theta)
        for kind in ("stairs_up", "stairs_down"):
            idx = np.flatnonzero(act == kind)
            if idx.size < 200:
                continue
            idx = idx[80:-80]  # away from the cross-fades
            q = deg[idx]
            r = res.setdefault(kind, {k: [] for k in ("rom_l", "rom_r", "peak_l", "peak_r",
                                                       "cadence", "rom_diff")})
            r["rom_l"].append(float(np.ptp(q[:, 0])))
            r["rom_r"].append(float(np.ptp(q[:, 1])))
            stand = p.stand_flexion_deg
            r["peak_l"].append(float(q[:, 0].max() - stand[0]))
            r["peak_r"].append(float(q[:, 1].max() - stand[1]))
            r["rom_diff"].append(abs(r["rom_l"][-1] - r["rom_r"][-1]))
            pk, _ = find_peaks(q[:, 0], distance=60)
            if pk.size >= 2:
                stride = float(np.median(np.diff(pk))) * 0.01
                r["cadence"].append(120.0 / stride)
                for a, b in zip(pk[:-1], pk[1:], strict=True):
                    seg = q[a:b + 1, 0]
                    cycles.setdefault(kind, []).append(
                        np.interp(np.linspace(0, 1, 101), np.linspace(0, 1, seg.size), seg))
    summary: dict[str, Any] = {"participants": n}
    for kind, r in res.items():
        summary[kind] = {k: {"mean": float(np.mean(v)), "sd": float(np.std(v, ddof=1)),
                             "min": float(np.min(v)), "max": float(np.max(v))}
                         for k, v in r.items() if v}
        summary[kind]["published"] = PUBLISHED_STAIRS[kind]
    summary["cycles"] = {k: np.array(v).tolist() for k, v in cycles.items()}
    return summary
