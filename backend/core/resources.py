"""Where the application's files are: in the installed package or in a clone.

A wheel carries the console's pages and modules, the npm files the pages load (uPlot,
Swagger UI), the Alembic migrations and the built guide in `backend/_bundled/`, copied
there by `setup.py` when the wheel is built. A clone has no such folder (it is never
committed): the same files are read where they live, `frontend/`, `migrations/` and
the MkDocs output `site/`. Everything that reads one of these goes through here, so
nothing else needs to know which of the two it runs from.

Data (database, device key, models, pid files) never goes into site-packages: a clone
keeps it in its own `var/`, an installed package in the platform's data folder
(`$XDG_DATA_HOME/exostudy`, by default `~/.local/share/exostudy`). `EXOSTUDY_DATA_DIR`
moves it anywhere; the single `EXOSTUDY_*` settings still override each file.
"""

from __future__ import annotations

import os
from importlib import metadata
from pathlib import Path

#: The package folder that a built wheel fills (see setup.py).
BUNDLE = Path(__file__).resolve().parents[1] / "_bundled"
#: The clone's root, if this code runs from one (unused when installed).
CHECKOUT = Path(__file__).resolve().parents[2]


def installed() -> bool:
    """True when running from an installed wheel (its bundle is present)."""
    return (BUNDLE / "frontend").is_dir()


def _root() -> Path:
    return BUNDLE if installed() else CHECKOUT


def frontend_dir() -> Path:
    """`pages/`, `static/` and the npm files under `node_modules/` (same layout in both)."""
    return _root() / "frontend"


def migrations_dir() -> Path:
    """The Alembic script folder (`env.py`, `versions/`)."""
    return _root() / "migrations"


def guide_dir() -> Path:
    """The built MkDocs site served at /guide (in a clone: `mkdocs build` makes `site/`)."""
    return BUNDLE / "guide" if installed() else CHECKOUT / "site"


def data_dir() -> Path:
    """Where the database, keys, models and pid files go by default."""
    explicit = os.environ.get("EXOSTUDY_DATA_DIR")
    if explicit:
        return Path(explicit).expanduser()
    if not installed():
        return CHECKOUT / "var"
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base).expanduser() / "exostudy"


def version() -> str:
    """The package version, from the installed metadata (one source: pyproject.toml)."""
    try:
        return metadata.version("exostudy")
    except metadata.PackageNotFoundError:  # a clone used without `pip install -e .`
        import tomllib

        with (CHECKOUT / "pyproject.toml").open("rb") as f:
            found: str = tomllib.load(f)["project"]["version"]
        return found
