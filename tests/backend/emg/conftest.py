"""EMG tests: liblsl on this machine only (the lab tests' configuration), and EMG files
in the test's own folder whatever the database."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from backend.core.config import Settings

os.environ.setdefault("LSLAPICFG", str(Path(__file__).parents[1] / "lab" / "lsl_api.cfg"))


@pytest.fixture
def settings(settings: Settings, tmp_path: Path) -> Settings:
    """The suite's settings with the EMG folder under the test's folder."""
    return settings.model_copy(update={"emg_dir": tmp_path / "emg"})
