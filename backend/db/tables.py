"""Every table module, imported so that `Base.metadata` is complete (Alembic, tests)."""

from backend.db import cohorts, emg, evidence_tables, hardware, lab, models, personalisation
from backend.db.models import Base

__all__ = ["Base", "cohorts", "emg", "evidence_tables", "hardware", "lab", "models",
           "personalisation"]
