"""The paper's evaluation order: UMC and PEC in balanced order across the study's
participants, E-UMC after them; and the blinded labels participants see.

A participant's position in the study (by enrolment, i.e. id order) decides: even
positions get UMC first, odd positions PEC first, so any two consecutive participants
balance each other. Labels are letters in the order the participant meets the
controllers ("A" first), so the label itself says nothing about the controller.
"""

from __future__ import annotations

LABELS = ("A", "B", "C")


def controller_order(position: int, include_eumc: bool = True) -> list[str]:
    """Controllers in the order participant number `position` (0-based) evaluates them."""
    if position < 0:
        raise ValueError("position must be >= 0")
    first = ["umc", "pec"] if position % 2 == 0 else ["pec", "umc"]
    return [*first, "eumc"] if include_eumc else first


def blinded_labels(order: list[str]) -> dict[str, str]:
    """Controller name -> label, in the order met."""
    return {c: LABELS[i] for i, c in enumerate(order)}
