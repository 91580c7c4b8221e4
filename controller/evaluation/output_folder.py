"""A folder that a report writes its files into.

The study results (`exostudy results`) and the virtual cohort (`exostudy cohort`) both
write tables and figures into one folder and report which files they wrote, in order.
"""

from __future__ import annotations

from pathlib import Path


class OutputFolder:
    """Creates the folder and records every file written into it, in order."""

    def __init__(self, path: Path) -> None:
        path.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.written: list[Path] = []

    def put(self, name: str, data: str | bytes) -> None:
        """Write `data` (text or bytes) as `name` inside the folder."""
        path = self.path / name
        if isinstance(data, str):
            path.write_text(data)
        else:
            path.write_bytes(data)
        self.written.append(path)
