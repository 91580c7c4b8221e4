"""The instruments that ship with ExoStudy, and putting them in the database.

They are JSON files next to this module (data, like any imported definition), loaded
and validated by the same code that validates a study's own file.
"""

from __future__ import annotations

import json
import logging
from functools import lru_cache
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db.models import QuestionnaireInstrument
from backend.questionnaires.definition import InstrumentDefinition

log = logging.getLogger(__name__)

INSTRUMENTS_DIR = Path(__file__).resolve().parent / "instruments"


@lru_cache(maxsize=1)
def built_in_definitions() -> tuple[InstrumentDefinition, ...]:
    """Every built-in definition, validated (a broken file fails loudly at start-up)."""
    return tuple(
        InstrumentDefinition.model_validate(json.loads(path.read_text(encoding="utf-8")))
        for path in sorted(INSTRUMENTS_DIR.glob("*.json"))
    )


def ensure_built_ins(session: Session) -> int:
    """Insert the built-in instruments missing from the database; returns how many.

    An existing key and version is never overwritten: responses were scored with it. A
    built-in whose stored definition differs means someone edited a released file
    without bumping its version, which is logged.
    """
    added = 0
    for definition in built_in_definitions():
        row = session.scalars(select(QuestionnaireInstrument).where(
            QuestionnaireInstrument.built_in.is_(True),
            QuestionnaireInstrument.key == definition.key,
            QuestionnaireInstrument.version == definition.version)).first()
        data = definition.model_dump(mode="json")
        if row is None:
            session.add(QuestionnaireInstrument(
                key=definition.key, version=definition.version, title=definition.title,
                definition=data, built_in=True))
            added += 1
        elif row.definition != data:
            log.warning("built-in instrument %s %s differs from the stored one; bump its "
                        "version instead of editing it", definition.key, definition.version)
    session.commit()
    return added


def built_in_keys() -> frozenset[str]:
    """Keys a study's own instrument may not use: a participant shown "sus" must get
    the shipped SUS, never a study's file that only borrows its name."""
    return frozenset(d.key for d in built_in_definitions())
