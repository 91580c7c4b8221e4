"""Scoring a set of answers with an instrument definition.

Raw answers are never summed directly: every answer is reversed and shifted as the
definition says first (the classic SUS bug is summing raw 1-5 answers).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from backend.questionnaires.definition import Aggregation, InstrumentDefinition


class AnswerError(ValueError):
    """Answers that cannot be scored; `problems` maps an item id to what is wrong."""

    def __init__(self, problems: dict[str, str]) -> None:
        self.problems = problems
        super().__init__("; ".join(f"{k}: {v}" for k, v in problems.items()))


@dataclass(frozen=True)
class Score:
    """A scored form: the total, each subscale, and the answers actually used (with any
    neutral substitutions) so the stored record reproduces the score."""

    score: float
    subscales: dict[str, float] = field(default_factory=dict)
    answers: dict[str, float] = field(default_factory=dict)
    substituted: tuple[str, ...] = ()


def aggregate(values: Sequence[float], agg: Aggregation) -> float:
    """Sum or mean of already reversed and shifted item values, times the multiplier."""
    total = float(sum(values))
    if agg.method == "mean":
        total /= len(values)
    # Round away binary noise (0.1 * 3) so stored scores compare exactly.
    return round(total * agg.multiplier, 9)


def validate_answers(
    definition: InstrumentDefinition, answers: Mapping[str, int | float | None]
) -> tuple[dict[str, float], tuple[str, ...]]:
    """Check answers against the definition; returns the complete answers (missing ones
    substituted if the policy allows) and which items were substituted."""
    scale = definition.scale
    item_ids = [it.id for it in definition.items]
    problems: dict[str, str] = {}
    for key in answers:
        if key not in item_ids:
            problems[key] = "no such item in this instrument"
    complete: dict[str, float] = {}
    substituted: list[str] = []
    for item_id in item_ids:
        value = answers.get(item_id)
        if value is None:
            if definition.missing.policy == "neutral":
                complete[item_id] = definition.neutral
                substituted.append(item_id)
            else:
                problems[item_id] = "missing answer"
            continue
        # Range first: comparisons work for any int and NaN, float() does not.
        if isinstance(value, bool) or not scale.min <= value <= scale.max:
            problems[item_id] = (f"{value!r} is outside the scale {scale.min}..{scale.max}")
        elif not math.isfinite(value) or float(value) != int(value):
            problems[item_id] = f"must be a whole number from {scale.min} to {scale.max}"
        else:
            complete[item_id] = float(value)
    if problems:
        raise AnswerError(problems)
    return complete, tuple(substituted)


def _item_values(definition: InstrumentDefinition, answers: Mapping[str, float],
                 items: Sequence[str], agg: Aggregation) -> list[float]:
    scale = definition.scale
    reverse = set(definition.reverse_scored)
    values = []
    for item_id in items:
        v = answers[item_id]
        if item_id in reverse:
            v = scale.min + scale.max - v
        if agg.from_min:
            v -= scale.min
        values.append(v)
    return values


def score(definition: InstrumentDefinition,
          answers: Mapping[str, int | float | None]) -> Score:
    """Validate and score one form. Raises `AnswerError` naming every bad item."""
    complete, substituted = validate_answers(definition, answers)
    item_ids = [it.id for it in definition.items]
    total = aggregate(_item_values(definition, complete, item_ids, definition.aggregation),
                      definition.aggregation)
    subscales = {}
    for sub in definition.subscales:
        agg = sub.aggregation or definition.aggregation
        subscales[sub.id] = aggregate(_item_values(definition, complete, sub.items, agg), agg)
    return Score(score=total, subscales=subscales, answers=complete, substituted=substituted)
