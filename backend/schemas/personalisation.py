"""Request and response bodies for personal model sets and prior sets (issue 30)."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from backend.schemas.fields import MAX_ID, UtcDatetime
from controller.intent.learned_priors import (
    DEFAULT_FORGETTING,
    DEFAULT_PSEUDO_COUNT,
    LearnedPriors,
)
from controller.intent.personal_models import DEFAULT_TAU, MIN_PARTICIPANT_DEMOS
from controller.intent.prior_safety import DEFAULT_FLOOR

Id = Annotated[int, Field(ge=1, le=MAX_ID)]


class PersonalModelSetIn(BaseModel):
    """Fit a participant's personal model set (a background job) from their labelled
    demonstrations: the segments of a demonstration block (`demonstration_trial_id`:
    every labelled segment of that trial), and/or chosen trial segments and recording
    segments of this participant.

    `method`: `map` adapts the population set `population_model_set_id` to the
    demonstrations (means only, relevance factor `tau`); `participant-only` fits PPCA
    from the demonstrations alone (at least `min_per_motion` of each motion)."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(min_length=1, max_length=200)
    method: Literal["map", "participant-only"] = "map"
    population_model_set_id: Id | None = None
    demonstration_trial_id: Id | None = None
    trial_segment_ids: list[Id] = Field(default_factory=list, max_length=10_000)
    segment_ids: list[Id] = Field(default_factory=list, max_length=10_000)
    tau: float = Field(default=DEFAULT_TAU, gt=0.0, le=1000.0)
    min_per_motion: int = Field(default=MIN_PARTICIPANT_DEMOS, ge=2, le=100)
    latent_dim: int | None = Field(default=None, ge=1, le=200)

    @model_validator(mode="after")
    def _sources(self) -> PersonalModelSetIn:
        if self.demonstration_trial_id is None and not self.trial_segment_ids \
                and not self.segment_ids:
            raise ValueError("give the demonstrations: demonstration_trial_id, "
                             "trial_segment_ids or segment_ids")
        if self.method == "map" and self.population_model_set_id is None:
            raise ValueError("population_model_set_id: the map method adapts a population "
                             "model set; name it")
        return self


class PriorSetIn(BaseModel):
    """Learn a participant's priors, always projected onto the safety bound of the
    utility set `utility_set_id` (its floors `floor`).

    - `dirichlet`: from the participant's confirmed motions in time order: labelled
      trial segments, labelled recording segments (`include_recordings`) and, with
      `gait_trials_as_other`, each completed walking or stairs trial as one "other"
      motion; continuing `previous_prior_set_id`'s counts when given (motions it already
      learned from are not counted twice).
    - `label-shift-em`: from unconfirmed use: one posterior per motion of the
      participant's completed UMC and E-UMC trials (each segmented lift at its peak and
      each `window_s` outside lifts), the EM estimate of Saerens et al.
    - `equal`: the paper's equal priors as a version of their own.
    - `import`: `values` given as they are; refused (422) unless inside the bound (they
      are never projected: a lab that imports priors gets exactly those or none)."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(min_length=1, max_length=200)
    method: Literal["dirichlet", "label-shift-em", "equal", "import"] = "dirichlet"
    utility_set_id: Id
    previous_prior_set_id: Id | None = None
    include_recordings: bool = True
    gait_trials_as_other: bool = True
    pseudo_count: float = Field(default=DEFAULT_PSEUDO_COUNT, gt=0.0, le=1e6)
    forgetting: float = Field(default=DEFAULT_FORGETTING, gt=0.0, le=1.0)
    floor: float = Field(default=DEFAULT_FLOOR, ge=DEFAULT_FLOOR, le=0.25, description=(
        "least prior of every motion; at least the default, so every motion stays "
        "recognisable"))
    window_s: float = Field(default=5.0, ge=0.5, le=600.0)
    values: list[float] | None = Field(default=None, min_length=4, max_length=4, description=(
        "import only: squat, stoop_left, stoop_right, other"))

    @field_validator("values")
    @classmethod
    def _finite(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and not all(math.isfinite(x) for x in v):
            raise ValueError("values must be finite numbers")
        return v

    @model_validator(mode="after")
    def _values_for_import(self) -> PriorSetIn:
        if (self.method == "import") != (self.values is not None):
            raise ValueError("values: give them with method import, and only then")
        return self


class PriorSetOut(BaseModel):
    """A participant's prior set; `document` is the `LearnedPriors` JSON (values the
    controller uses, the unbounded estimate, counts, sources)."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    study_id: int
    participant_id: int
    version: int
    name: str
    method: str
    status: str
    utility_set_id: int | None
    previous_id: int | None
    params: dict[str, Any]
    document: dict[str, Any] | None
    error: str
    created_at: UtcDatetime
    problem: str | None = Field(default=None, description=(
        "why the stored document is not a valid priors document (then `document` is "
        "null and no plan or trial can use the set); null when it is valid"))

    @model_validator(mode="before")
    @classmethod
    def _checked_document(cls, data: Any) -> Any:
        """A stored row altered into an invalid document is listed as such, not a
        failed answer: one bad row never hides the others."""
        if not isinstance(data, dict):
            data = {k: getattr(data, k) for k in cls.model_fields if hasattr(data, k)}
        doc = data.get("document")
        if doc is None:
            return data
        try:
            LearnedPriors.from_json(doc)
        except ValueError as exc:
            return {**data, "document": None, "problem": str(exc)}
        return data


class PersonalModelSetOut(BaseModel):
    """A personal model set with its provenance (the population set, the
    demonstrations, the method); the fitted document via `/api/model-sets/{id}/document`."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    study_id: int
    name: str
    status: str
    kind: str
    method: str
    participant_id: int | None
    base_model_set_id: int | None
    params: dict[str, Any]
    segment_ids: list[int]
    error: str
    created_at: UtcDatetime
    job_id: int | None = None
