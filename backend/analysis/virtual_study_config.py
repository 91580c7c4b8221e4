"""What a virtual study runs and what it reports: its settings, the constants of its
protocol, the report it returns and its one error. Apart from the phases so that each
phase, the entry point (`backend.analysis.virtual_study`) and the tests read one
definition."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from backend.analysis.virtual_study_speeds import COLLECTION_SPEED, DEFAULT_SPEED
from controller.device.base import MAX_SPEED

RATE_SETTINGS: dict[str, float | None] = {"paper-rates": None, "100hz": 100.0}
#: liblsl's configuration for the virtual study (written into its folder): streams are
#: found on this machine only, by multicast on the machine scope and unicast to the
#: loopback address, so the simulated amplifier and the server need no network.
LSL_CONFIG = ("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
              "[lab]\nKnownPeers = {127.0.0.1}\n")
#: A wait on the worker fails only after this many seconds without progress (ticks,
#: job progress): a loaded machine makes the study slower, never wrong.
STALL_S = 120.0
#: What the virtual studies' exports say about themselves (BIDS' dataset description):
#: simulated data made by this software, free of any right (CC0).
DATASET_INFO: dict[str, Any] = {
    "authors": ["ExoStudy virtual study", "ExoStudy contributors"],
    "license": "CC0-1.0",
    "institution_name": "none (simulated participants)",
    "institution_address": "none (simulated participants)",
    "institution_department": "none (simulated participants)",
    "instructions": "none: virtual participants follow the simulator's script",
}
#: Tables written per rate setting (questionnaires are left out, see
#: `backend.analysis.virtual_study`).
WRITTEN_TABLES = ("performance", "performance_by_kind", "false_positives", "onset_to_lock",
                  "lifts")
#: See `VirtualStudyConfig.emg_idle_speed`.
EMG_IDLE_SPEED = 1.0
#: The simulated amplifier's stream (`SimulatedDevice` with `emg_lsl`) and its spare inputs.
EMG_STREAM = "ExoStudy-SimEMG"
EMG_SPARE = ("spare_1", "spare_2", "spare_3", "spare_4")
#: The EMG study's settings: the project's chain with a 50 Hz notch (the simulated
#: amplifier hums at 50 Hz), normalised to the task peak (no MVC in a simulation).
EMG_SETTINGS: dict[str, Any] = {"processing": {"notch_hz": 50}, "normalisation": "task_peak",
                                "mains_hz": 50}
QUESTIONNAIRE_NOTE = ("Questionnaires (SUS, EUS, preference) are not part of a virtual "
                      "study: virtual participants give no answers, and none are invented.")


@dataclass(frozen=True)
class VirtualStudyConfig:
    """What to run. Seeds: evaluation participant j (0-based) is `seed*100 + 1 + j`,
    data-collection participant i is `seed*100 + 50 + i`."""

    out: Path
    participants: int = 8
    data_participants: int = 6
    eumc: int = 3
    seed: int = 1
    speed: float = DEFAULT_SPEED
    collection_speed: float = COLLECTION_SPEED
    eval_script: str = "paper-evaluation"
    data_scripts: tuple[str, ...] = ("squat-sequence", "stoop-sequence")
    rates: tuple[str, ...] = tuple(RATE_SETTINGS)
    margin_s: float = 6.0
    model_evaluation: bool = True
    #: EMG on LSL and the baseline conditions in the first rate setting's study (off:
    #: the paper's protocol alone, which is several times faster).
    emg: bool = False
    baseline_script: str = "lift-evaluation"
    #: Simulator speed-up in the pause after a trial that records EMG, while the
    #: server's inlet catches up with what the sped-up trial produced (LSL buffers it).
    emg_idle_speed: float = EMG_IDLE_SPEED

    def __post_init__(self) -> None:
        if self.participants < 1:
            raise ValueError("participants: need at least 1")
        if self.data_participants < 2:
            raise ValueError("data_participants: need at least 2 to fit and cross-validate")
        if not 0 <= self.eumc <= self.participants:
            raise ValueError(f"eumc: must be within 0..{self.participants}")
        if not 1.0 <= self.speed <= MAX_SPEED:
            raise ValueError(f"speed: must be within 1..{MAX_SPEED:g} times real time")
        if not 1.0 <= self.collection_speed <= MAX_SPEED:
            raise ValueError(
                f"collection_speed: must be within 1..{MAX_SPEED:g} times real time")
        unknown = [r for r in self.rates if r not in RATE_SETTINGS]
        if unknown or not self.rates:
            raise ValueError(f"rates: choose from {', '.join(RATE_SETTINGS)}")
        if not 0 <= self.seed <= 20_000_000:
            raise ValueError("seed: must be within 0..20000000")

    def eval_seed(self, j: int) -> int:
        """Seed of evaluation participant j."""
        return self.seed * 100 + 1 + j

    def data_seed(self, i: int) -> int:
        """Seed of data-collection participant i."""
        return self.seed * 100 + 50 + i


@dataclass
class TrialTiming:
    """How one trial ran: wall time, ticks, the rate reached, device-time gaps."""

    trial_id: int
    study: str
    participant: str
    controller: str
    wall_s: float
    ticks: int
    ticks_per_s: float
    gaps: int
    calibration_attempts: int = 0


@dataclass
class VirtualStudyReport:
    """What a run did and where it wrote it."""

    out: Path
    wall_s: float = 0.0
    phases: dict[str, float] = field(default_factory=dict)
    studies: dict[str, int] = field(default_factory=dict)
    model_set_id: int = 0
    utility_set_id: int = 0
    trials: list[TrialTiming] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def as_json(self) -> dict[str, Any]:
        """JSON-able form (written as `summary.json`)."""
        d = asdict(self)
        d["out"] = str(self.out)
        return d


class VirtualStudyError(RuntimeError):
    """The server refused a step; the message names it."""
