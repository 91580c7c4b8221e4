"""Benchmark results as files, so the guide's benchmark tables are the benchmarks' own
output rather than numbers typed into a page.

A benchmark calls `record(...)` once at the end of its run; that writes
`bench/results/<name>.json` with the table and the conditions it was measured under
(load average before and after, cores, date, Python). The guide's build
(`tools/docs/hooks.py`) replaces `<!-- bench: name -->` in a page with that table.
Commit the JSON file with the code it measured.
"""

from __future__ import annotations

import json
import os
import platform
from datetime import UTC, datetime
from pathlib import Path

RESULTS_DIR = Path(__file__).resolve().parent / "results"


def load_average() -> float:
    """The one-minute load average, the figure every table quotes."""
    return round(os.getloadavg()[0], 1)


def record(name: str, command: str, columns: list[str], rows: list[list[object]],
           load_before: float, note: str = "") -> Path:
    """Write one benchmark's table and its conditions to `bench/results/<name>.json`."""
    if any(len(r) != len(columns) for r in rows):
        raise ValueError(f"{name}: every row needs {len(columns)} cells")
    doc = {
        "name": name,
        "command": command,
        "measured": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "load_average": {"before": load_before, "after": load_average()},
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "columns": columns,
        "rows": rows,
        "note": note,
    }
    RESULTS_DIR.mkdir(exist_ok=True)
    path = RESULTS_DIR / f"{name}.json"
    path.write_text(json.dumps(doc, indent=1) + "\n")
    return path
