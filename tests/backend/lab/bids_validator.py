"""The official BIDS validator (npm `bids-validator`, installed by `make install` under
tools/bids) run on a folder; its errors, as (code, key, files)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
VALIDATOR = ROOT / "tools" / "bids" / "node_modules" / ".bin" / "bids-validator"


def validate(folder: Path) -> list[tuple[int, str, list[str]]]:
    """Run the validator; the errors it reports (warnings are left out)."""
    assert VALIDATOR.is_file(), f"{VALIDATOR} is missing: run `make install`"
    proc = subprocess.run([str(VALIDATOR), str(folder), "--json"], capture_output=True,
                          text=True, timeout=300, check=False)
    # The JSON report comes first; the validator may print more after it.
    report, _ = json.JSONDecoder().raw_decode(proc.stdout)
    return [(e["code"], e["key"], [f["file"]["relativePath"] for f in e["files"]
                                   if f.get("file")])
            for e in report["issues"]["errors"]]
