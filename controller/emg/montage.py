"""A study's EMG montage: which recorded channel is which muscle and side, and how its
electrodes were placed, so a stream or a file's channels map to muscles by label.

Placement is free text (the SENIAM recommendation followed, or the lab's own
description); electrode type, inter-electrode distance and reference are what BIDS-EMG
and the CEDE reporting checklist ask a lab to state.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Literal, get_args

Muscle = Literal["erector_spinae_lumbar", "erector_spinae_thoracic", "gluteus_maximus",
                 "biceps_femoris", "rectus_abdominis", "rectus_femoris"]
MUSCLES: tuple[str, ...] = get_args(Muscle)
Side = Literal["left", "right"]
SIDES: tuple[str, ...] = get_args(Side)


class MontageError(ValueError):
    """A montage, or a match of channel labels against one, is not usable."""


def normalise_label(label: str) -> str:
    """Label for matching: case-folded, with runs of spaces, dashes, dots and
    underscores as one underscore ("ES-L lumbar" and "es_l_LUMBAR" match)."""
    return re.sub(r"[\s\-_.:/]+", "_", label.strip().casefold()).strip("_")


@dataclass(frozen=True, slots=True)
class MontageChannel:
    """One channel: its label in the recording, the muscle and side, and the electrodes."""

    label: str
    muscle: Muscle
    side: Side
    placement: str = ""
    electrode_type: str = ""
    inter_electrode_distance_mm: float | None = None
    reference: str = ""

    def __post_init__(self) -> None:
        if not normalise_label(self.label):
            raise MontageError(f"channel label {self.label!r} is empty")
        if self.muscle not in MUSCLES:
            raise MontageError(f"channel {self.label!r}: unknown muscle {self.muscle!r}; "
                               f"use one of {MUSCLES}")
        if self.side not in SIDES:
            raise MontageError(f"channel {self.label!r}: side must be 'left' or 'right', "
                               f"got {self.side!r}")
        ied = self.inter_electrode_distance_mm
        if ied is not None and not 0 < ied <= 100:
            raise MontageError(f"channel {self.label!r}: inter-electrode distance must be "
                               f"in (0, 100] mm, got {ied}")

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MontageChannel:
        """Inverse of `to_dict`; unknown keys are an error."""
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(data) - known)
        if unknown:
            raise MontageError(f"montage channel: unknown keys {unknown}")
        return cls(**data)


@dataclass(frozen=True, slots=True)
class ChannelMatch:
    """Labels of a recording matched against a montage.

    `indices[i]` is the recording's column of montage channel i, or None when no label
    matched it; `unmatched_labels` are recording labels no montage channel claims.
    """

    indices: tuple[int | None, ...]
    unmatched_labels: tuple[str, ...]
    missing: tuple[str, ...]

    @property
    def complete(self) -> bool:
        """Every montage channel was found."""
        return not self.missing


@dataclass(frozen=True, slots=True)
class Montage:
    """The channels of a study's EMG, each (muscle, side) at most once."""

    channels: tuple[MontageChannel, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not self.channels:
            raise MontageError("a montage needs at least one channel")
        labels = [normalise_label(c.label) for c in self.channels]
        dup = sorted({c.label for c, n in zip(self.channels, labels, strict=True)
                      if labels.count(n) > 1})
        if dup:
            raise MontageError(f"montage labels must be unique; repeated: {dup}")
        pairs = [(c.muscle, c.side) for c in self.channels]
        twice = sorted({p for p in pairs if pairs.count(p) > 1})
        if twice:
            raise MontageError(f"each muscle and side at most once; repeated: {twice}")

    def to_dict(self) -> dict[str, Any]:
        """Plain form for storage and exports."""
        return {"channels": [c.to_dict() for c in self.channels]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Montage:
        """Inverse of `to_dict`."""
        chans = data.get("channels")
        if not isinstance(chans, list):
            raise MontageError("montage: 'channels' must be a list")
        return cls(tuple(MontageChannel.from_dict(c) for c in chans))

    def match(self, labels: Sequence[str]) -> ChannelMatch:
        """Find each montage channel among a recording's channel labels (normalised
        comparison, see `normalise_label`); ambiguous recording labels are an error."""
        norm = [normalise_label(lb) for lb in labels]
        repeated = sorted({lb for lb, n in zip(labels, norm, strict=True) if norm.count(n) > 1})
        if repeated:
            raise MontageError(f"recording has channels with the same label: {repeated}")
        where = {n: i for i, n in enumerate(norm)}
        indices = tuple(where.get(normalise_label(c.label)) for c in self.channels)
        claimed = {i for i in indices if i is not None}
        return ChannelMatch(indices,
                            tuple(lb for i, lb in enumerate(labels) if i not in claimed),
                            tuple(c.label for c, i in zip(self.channels, indices, strict=True)
                                  if i is None))

    def require(self, labels: Sequence[str]) -> tuple[int, ...]:
        """The recording's column of every montage channel, or an error naming the
        montage labels not found and the recording labels on offer."""
        m = self.match(labels)
        if not m.complete:
            raise MontageError(f"channels {list(m.missing)} of the montage are not in the "
                               f"recording, whose labels are {list(labels)}")
        return tuple(i for i in m.indices if i is not None)
