"""The lab tests' LSL setting: liblsl reads `LSLAPICFG` at its first call, and conftest
files are imported at collection, before any test starts a server."""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("LSLAPICFG", str(Path(__file__).with_name("lsl_api.cfg")))
