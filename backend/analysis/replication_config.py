"""What a replication runs (`ReplicationConfig`) and what its report shows
(`Replication`): the data shared by `replication_run` (which fills it) and
`replication_report` (which writes it), kept apart so neither imports the other's work.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from controller.evaluation.cohort import MAX_PARTICIPANTS
from controller.evaluation.paper_claims import DEFAULT_SEEDS, ClaimResult
from controller.evaluation.tables import Table

Engine = Literal["study", "cohort"]
#: The engine a run uses unless asked otherwise: the cohort engine replays the same
#: protocol in-process in minutes; the study engine (the whole live chain per seed)
#: takes about 100 minutes for the default seeds.
DEFAULT_ENGINE: Engine = "cohort"
#: Participants of the personalisation section unless asked otherwise: the smallest
#: cohort the personalisation evidence is judged on (40), one seed. Measured: 154 s
#: (2 cores shared with other jobs, load 5-7), about 2.5 minutes on top of the seeds.
DEFAULT_PERSONALISATION = 40


@dataclass(frozen=True)
class ReplicationConfig:
    """What to run; see `backend.analysis.replication_run`."""

    out: Path
    seeds: int = DEFAULT_SEEDS
    first_seed: int = 1
    engine: Engine = DEFAULT_ENGINE
    from_db: tuple[Path, ...] = ()
    participants: int = 8
    eumc: int = 3
    data_participants: int = 6
    offset_participants: int = 60
    stair_participants: int = 20
    #: Virtual participants of the personalisation section (one cohort, seed
    #: `first_seed`; `controller.evaluation.personalisation`); 0 leaves it out.
    personalisation_participants: int = DEFAULT_PERSONALISATION

    def __post_init__(self) -> None:
        if not self.from_db and not 2 <= self.seeds <= 50:
            raise ValueError(f"seeds: need 2..50 for an interval, got {self.seeds}")
        if self.engine not in ("study", "cohort"):
            raise ValueError(f"engine: choose study or cohort, got {self.engine!r}")
        if not 2 <= self.participants <= 40:
            raise ValueError("participants: must be within 2..40")
        if not 1 <= self.eumc <= self.participants:
            raise ValueError(f"eumc: must be within 1..{self.participants}")
        if not 2 <= self.data_participants <= 12:
            raise ValueError("data_participants: must be within 2..12")
        if not 4 <= self.offset_participants <= 2000:
            raise ValueError("offset_participants: must be within 4..2000")
        if not 2 <= self.stair_participants <= 500:
            raise ValueError("stair_participants: must be within 2..500")
        if self.personalisation_participants != 0 and not (
                3 <= self.personalisation_participants <= MAX_PARTICIPANTS):
            raise ValueError("personalisation_participants: 0 (leave the section out) or "
                             f"3..{MAX_PARTICIPANTS} (each participant's population models "
                             "need two others)")
        for p in self.from_db:
            if not Path(p).is_file():
                raise FileNotFoundError(f"--from-db: no database file at {p}")

    def seed_list(self) -> list[int]:
        """The seeds run (none with `from_db`)."""
        return [] if self.from_db else list(range(self.first_seed,
                                                  self.first_seed + self.seeds))


@dataclass
class SeedResult:
    """One seed's measures and where they came from."""

    label: str
    measures: dict[str, float]
    source: str
    wall_s: float = 0.0


@dataclass
class Replication:
    """Everything the report shows."""

    config: ReplicationConfig
    seeds: list[SeedResult] = field(default_factory=list)
    claims: list[ClaimResult] = field(default_factory=list)
    checks: dict[str, float] = field(default_factory=dict)
    offsets: dict[str, Any] = field(default_factory=dict)
    stairs: dict[str, Any] = field(default_factory=dict)
    #: The first seed's tables (the paper's layout), by name.
    first_tables: dict[str, Table] = field(default_factory=dict)
    #: Sections given as Markdown by the modules that compute them (muscle activity),
    #: by name: the HTML report shows their paragraphs and tables
    #: (`replication_report.markdown_blocks`), beside their figures.
    sections: dict[str, str] = field(default_factory=dict)
    figures: dict[str, tuple[bytes, bytes]] = field(default_factory=dict)
    #: The personalisation study's `personalisation.json` document
    #: (`controller.evaluation.personalisation_report.analysis_json`); empty if skipped.
    personalisation: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    phases: dict[str, float] = field(default_factory=dict)
