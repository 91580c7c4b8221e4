"""The BIDS validator (the schema-based one, PyPI `bids-validator-deno`, a dev
dependency that brings its own Deno runtime; it runs offline) on a folder: its issues,
as (severity, code, sub-code, file)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

VALIDATOR = Path(sys.executable).parent / "bids-validator-deno"


def issues(folder: Path) -> list[tuple[str, str, str, str]]:
    """Every error and warning the validator reports, each row of every TSV checked."""
    assert VALIDATOR.is_file(), f"{VALIDATOR} is missing: pip install -e '.[dev]'"
    proc = subprocess.run([str(VALIDATOR), str(folder), "--format", "json",
                           "--max-rows", "-1"],
                          capture_output=True, text=True, timeout=300, check=False)
    assert proc.stdout, f"the validator printed nothing (exit {proc.returncode}): " \
        f"{proc.stderr[-2000:]}"
    report = json.loads(proc.stdout)
    return [(i["severity"], i["code"], i.get("subCode") or "", i.get("location") or "")
            for i in report["issues"]["issues"]]


def validate(folder: Path) -> list[tuple[str, str, str, str]]:
    """The errors alone (warnings left out)."""
    return [i for i in issues(folder) if i[0] == "error"]
