"""The instrument definition format: what a questionnaire file must say to be scored.

A definition is data a study can read and import, not code: items, the response scale,
reverse-scored items, subscales, how scores aggregate, the score range it promises and
what to do with a missing answer. Validation catches the mistakes that would silently
give wrong scores (a reverse item that does not exist, a declared range the aggregation
cannot produce).
"""

from __future__ import annotations

import math
import unicodedata
from collections import Counter
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

#: A study's own instruments (imported) must keep their form usable on a tablet: at most
#: this many points on the scale (0 to 100 is the widest), and at most this many answer
#: choices on one form (items x points; the SUS has 50, a 0-100 rating of 49 items
#: 4,949). A scale of -1000..1000 with 200 items once made a form of 400,200 choices
#: that took two minutes to show.
MAX_SCALE_POINTS = 101
MAX_FORM_CHOICES = 5_000
#: Items an instrument may have (any instrument: the format's own limit).
MAX_ITEMS = 200
#: Subscales an imported instrument may have; each holds at most every item once, and
#: `reverse_scored` names each item at most once: lists longer than the instrument
#: cannot mean anything, and thousands of entries only cost time to check and show.
MAX_SUBSCALES = 50

KEY_PATTERN = r"^[a-z][a-z0-9_-]{0,63}$"
VERSION_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,31}$"
ITEM_ID_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$"


class _Strict(BaseModel):
    # An unknown field in a definition file is almost always a typo ("reversed" for
    # "reverse_scored"); refusing it beats scoring without it.
    model_config = ConfigDict(extra="forbid")


class Item(_Strict):
    """One statement or question the participant answers on the response scale."""

    id: str = Field(pattern=ITEM_ID_PATTERN)
    text: str = Field(min_length=1, max_length=1000)


class ScaleLabel(_Strict):
    """The words shown at one point of the scale (usually the two ends)."""

    value: int
    label: str = Field(min_length=1, max_length=200)


class ResponseScale(_Strict):
    """Integer answers from `min` to `max` inclusive."""

    min: int = Field(ge=-1000, le=1000)
    max: int = Field(ge=-1000, le=1000)
    labels: list[ScaleLabel] = Field(default_factory=list)

    @model_validator(mode="after")
    def _ordered(self) -> ResponseScale:
        if self.max <= self.min:
            raise ValueError(f"max ({self.max}) must be greater than min ({self.min})")
        for lab in self.labels:
            if not self.min <= lab.value <= self.max:
                raise ValueError(f"label value {lab.value} is outside {self.min}..{self.max}")
        return self


class Aggregation(_Strict):
    """How item values become a score.

    Each answer is first reversed if its item is reverse-scored (`min + max - answer`),
    then, with `from_min`, shifted so the scale starts at 0 (`value - min`); the values
    are summed or averaged and multiplied by `multiplier`. SUS is `sum`, `from_min`,
    `multiplier` 2.5; a mean of 0-10 ratings is `mean` with multiplier 1.
    """

    method: Literal["sum", "mean"]
    from_min: bool = False
    multiplier: float = Field(default=1.0, gt=0.0, le=1e6)


class Subscale(_Strict):
    """A named subset of items scored on its own (aggregation defaults to the
    instrument's)."""

    id: str = Field(pattern=ITEM_ID_PATTERN)
    title: str = Field(min_length=1, max_length=200)
    items: list[str] = Field(min_length=1)
    aggregation: Aggregation | None = None


class ScoreRange(_Strict):
    """The lowest and highest score the instrument can give."""

    min: float
    max: float


class MissingPolicy(_Strict):
    """What an unanswered item does: `reject` the form (default) or substitute
    `neutral_value` (the scale midpoint if not given)."""

    policy: Literal["reject", "neutral"] = "reject"
    neutral_value: float | None = None


class Provenance(_Strict):
    """Where the item wording comes from, shown to experimenters with the instrument.

    `standard`: the published wording; `project`: written by the ExoStudy project;
    `study`: supplied by a study (for example its transcription of published items).
    """

    wording: Literal["standard", "project", "study"]
    source: str = Field(default="", max_length=1000)
    note: str = Field(default="", max_length=2000)


class InstrumentDefinition(_Strict):
    """A complete questionnaire definition (the format of an importable file)."""

    key: str = Field(pattern=KEY_PATTERN, description="short name, e.g. sus")
    version: str = Field(pattern=VERSION_PATTERN, description="e.g. 1.0")
    title: str = Field(min_length=1, max_length=200)
    instructions: str = Field(default="", max_length=4000)
    items: list[Item] = Field(min_length=1, max_length=MAX_ITEMS)
    scale: ResponseScale
    reverse_scored: list[str] = Field(default_factory=list)
    aggregation: Aggregation
    subscales: list[Subscale] = Field(default_factory=list)
    score_range: ScoreRange
    missing: MissingPolicy = Field(default_factory=MissingPolicy)
    provenance: Provenance

    @model_validator(mode="after")
    def _consistent(self) -> InstrumentDefinition:
        ids = [it.id for it in self.items]
        dupes = sorted({i for i in ids if ids.count(i) > 1})
        if dupes:
            raise ValueError(f"items: duplicate item ids {dupes}")
        known = set(ids)
        unknown = sorted(set(self.reverse_scored) - known)
        if unknown:
            raise ValueError(f"reverse_scored: unknown item ids {unknown}")
        sub_ids = [s.id for s in self.subscales]
        if len(set(sub_ids)) != len(sub_ids):
            raise ValueError("subscales: duplicate subscale ids")
        for sub in self.subscales:
            bad = sorted(set(sub.items) - known)
            if bad:
                raise ValueError(f"subscales.{sub.id}.items: unknown item ids {bad}")
        n = self.missing.neutral_value
        if n is not None and not self.scale.min <= n <= self.scale.max:
            raise ValueError(f"missing.neutral_value {n} is outside the scale "
                             f"{self.scale.min}..{self.scale.max}")
        lo, hi = self.reachable_range()
        if not (math.isclose(lo, self.score_range.min, abs_tol=1e-9)
                and math.isclose(hi, self.score_range.max, abs_tol=1e-9)):
            raise ValueError(f"score_range: declared {self.score_range.min}..{self.score_range.max}"
                             f" but the aggregation gives {lo:g}..{hi:g}")
        return self

    def reachable_range(self) -> tuple[float, float]:
        """The score of the worst and of the best possible answers."""
        from backend.questionnaires.scoring import aggregate

        n = len(self.items)
        lo = self.scale.min - (self.scale.min if self.aggregation.from_min else 0)
        hi = self.scale.max - (self.scale.min if self.aggregation.from_min else 0)
        return aggregate([lo] * n, self.aggregation), aggregate([hi] * n, self.aggregation)

    @property
    def neutral(self) -> float:
        """The value substituted for a missing answer under the `neutral` policy."""
        if self.missing.neutral_value is not None:
            return self.missing.neutral_value
        return (self.scale.min + self.scale.max) / 2


def label_words(label: str) -> str:
    """The words of a label as a reader sees them, for telling two labels apart:
    compatibility-normalised (NFKC: full-width letters and decomposed accents become the
    usual ones), without invisible format characters (category Cf: zero-width spaces,
    joiners, direction marks), case-folded, runs of whitespace made one space."""
    text = unicodedata.normalize("NFKC", label)
    text = "".join(ch for ch in text if unicodedata.category(ch) != "Cf")
    text = unicodedata.normalize("NFKC", text.casefold())
    return " ".join(text.split())


def _repeated(values: list[str]) -> list[str]:
    return sorted(v for v, n in Counter(values).items() if n > 1)


class ImportedScale(ResponseScale):
    """The scale of an imported instrument: at most `MAX_SCALE_POINTS` points, and at
    most one label per point, each with its own words."""

    labels: list[ScaleLabel] = Field(default_factory=list, max_length=MAX_SCALE_POINTS)

    @model_validator(mode="after")
    def _bounded(self) -> ImportedScale:
        points = self.max - self.min + 1
        if points > MAX_SCALE_POINTS:
            raise ValueError(f"{self.min}..{self.max} has {points} points; at most "
                             f"{MAX_SCALE_POINTS} are allowed (for example 0..100)")
        twice = sorted(v for v, n in Counter(lab.value for lab in self.labels).items()
                       if n > 1)
        if twice:
            raise ValueError(f"labels: more than one label for value(s) {twice[:10]}")
        words = [label_words(lab.label) for lab in self.labels]
        blank = [lab.value for lab, w in zip(self.labels, words, strict=True) if not w]
        if blank:
            raise ValueError(f"labels: the label at value(s) {blank[:10]} shows no words "
                             "(only spaces or invisible characters)")
        same = _repeated(words)
        if same:
            raise ValueError(f"labels: the same words at several values: {same[:5]} "
                             "(compared ignoring case, spacing, invisible characters and "
                             "character width)")
        return self


class ImportedSubscale(Subscale):
    """A subscale of an imported instrument: each item at most once."""

    items: list[str] = Field(min_length=1, max_length=MAX_ITEMS)

    @model_validator(mode="after")
    def _once_each(self) -> ImportedSubscale:
        twice = _repeated(self.items)
        if twice:
            raise ValueError(f"items: listed more than once {twice[:10]}")
        return self


class ImportedInstrument(InstrumentDefinition):
    """A definition a study imports: the format's rules, plus limits that keep its form
    usable (`ImportedScale`, at most `MAX_FORM_CHOICES` answer choices). Instruments
    stored before these limits are read as `InstrumentDefinition`, unchanged."""

    scale: ImportedScale
    reverse_scored: list[str] = Field(default_factory=list, max_length=MAX_ITEMS)
    # A narrower item type than the base's list[Subscale]: pydantic validates by it; mypy
    # sees list invariance (nothing appends a plain Subscale to an imported instrument).
    subscales: list[ImportedSubscale] = Field(  # type: ignore[assignment]
        default_factory=list, max_length=MAX_SUBSCALES)

    @model_validator(mode="after")
    def _lists_within_the_items(self) -> ImportedInstrument:
        # Each id at most once and (the format's check) each a known item: no list is
        # longer than the instrument's item count.
        twice = _repeated(self.reverse_scored)
        if twice:
            raise ValueError(f"reverse_scored: listed more than once {twice[:10]}")
        return self

    @model_validator(mode="after")
    def _form_size(self) -> ImportedInstrument:
        choices = len(self.items) * (self.scale.max - self.scale.min + 1)
        if choices > MAX_FORM_CHOICES:
            raise ValueError(f"the form would show {choices} answer choices ({len(self.items)}"
                             f" items x {self.scale.max - self.scale.min + 1} points); at most "
                             f"{MAX_FORM_CHOICES}: fewer items or a shorter scale")
        return self
