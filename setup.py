"""The wheel is the whole application: this build step bundles what runs beside the code.

`python -m build --wheel` (or any wheel build) copies into the package folder
`backend/_bundled/` of the build tree, never of the source tree:

- `frontend/pages` and `frontend/static` (page bodies, ES modules, style, icon);
- the npm files the pages load, from `frontend/node_modules` (installed by `make`): uPlot
  and the two Swagger UI files of /docs, each with its licence;
- `migrations/` (the Alembic environment and every revision);
- the guide: the MkDocs site built from `docs/` (`mkdocs build --strict`), served at
  /guide.

The folders stay where they are in the clone; `backend/core/resources.py` finds the
files in the bundle when installed and in the clone otherwise. An editable install
(`pip install -e .`, what `make` does) bundles nothing: it reads the clone.

The C device executable (`firmware/`) is not bundled: the wheel is pure Python
(`py3-none-any`), and a native program built for one machine would make it lie about
where it runs. The wheel ships the Python device simulator; the C one needs a clone.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent

#: npm package -> the files of it the app serves (and the licences that go with them).
NPM_FILES: dict[str, tuple[str, ...]] = {
    "uplot": ("LICENSE", "dist/uPlot.esm.js", "dist/uPlot.min.css"),
    "swagger-ui-dist": ("LICENSE", "NOTICE", "swagger-ui.css", "swagger-ui-bundle.js",
                        "swagger-ui-bundle.js.LICENSE.txt"),
}
_SKIP = shutil.ignore_patterns("__pycache__", "*.pyc")


class BuildWithAssets(build_py):
    """build_py, then the application's non-Python files into backend/_bundled/."""

    def run(self) -> None:
        editable = getattr(self, "editable_mode", False)
        if not editable and not ROOT.is_relative_to(Path(self.build_lib).resolve()):
            # A module deleted since the last build must not reach the wheel.
            shutil.rmtree(self.build_lib, ignore_errors=True)
        super().run()
        if editable:
            return  # an editable install reads the clone's own folders
        bundle = Path(self.build_lib) / "backend" / "_bundled"
        shutil.rmtree(bundle, ignore_errors=True)
        front = bundle / "frontend"
        for part in ("pages", "static"):
            shutil.copytree(ROOT / "frontend" / part, front / part, ignore=_SKIP)
        modules = ROOT / "frontend" / "node_modules"
        for package, files in NPM_FILES.items():
            for rel in files:
                src = modules / package / rel
                if not src.is_file():
                    raise SystemExit(f"setup.py: {src} is missing: run `make install` (npm ci "
                                     "in frontend/) before building the wheel")
                dst = front / "node_modules" / package / rel
                dst.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src, dst)
        shutil.copytree(ROOT / "migrations", bundle / "migrations", ignore=_SKIP)
        subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet",
                        "--config-file", str(ROOT / "mkdocs.yml"),
                        "--site-dir", str(bundle / "guide")], check=True, cwd=ROOT)


setup(cmdclass={"build_py": BuildWithAssets})
