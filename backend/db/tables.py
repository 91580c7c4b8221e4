"""Every table module, imported so that `Base.metadata` is complete (Alembic, tests)."""

from backend.db import evidence, models
from backend.db.models import Base

__all__ = ["Base", "evidence", "models"]
