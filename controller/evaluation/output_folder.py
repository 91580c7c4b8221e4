"""A folder that a report writes its files into.

The study results (`exostudy results`) and the virtual cohort (`exostudy cohort`) both
write tables and figures into one folder and report which files they wrote, in order.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from controller.private_files import make_private_dir, write_private


class OutputFolder:
    """Creates the folder and records every file written into it, in order.

    `private`: the report holds participant data (a study's results), so new folders
    are made 0700 and files 0600 whatever the umask (controller/private_files.py)."""

    def __init__(self, path: Path, *, private: bool = False) -> None:
        if private:
            make_private_dir(path)
        else:
            path.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.private = private
        self.written: list[Path] = []

    def put(self, name: str, data: str | bytes) -> None:
        """Write `data` (text or bytes) as `name` inside the folder."""
        path = self.path / name
        if self.private:
            write_private(path, data)
        elif isinstance(data, str):
            path.write_text(data)
        else:
            path.write_bytes(data)
        self.written.append(path)


def json_ready(x: Any) -> Any:
    """`x` with every non-finite float as None (JSON has no NaN), tuples as lists, keys
    as text and paths as text: the one conversion every report's JSON file goes through."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {str(k): json_ready(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_ready(v) for v in x]
    if isinstance(x, Path):
        return str(x)
    return x
