"""The virtual study's server and client work without the dev extras: nothing imports
httpx (or fastapi.testclient), and the plain HTTP client talks to a real uvicorn."""

from __future__ import annotations

import subprocess
import sys

from fastapi import FastAPI, Header

from backend.live.local_server import serving

NO_HTTPX = """
import sys
sys.modules["httpx"] = None  # as on an install without the dev extras
import backend.analysis.virtual_study, backend.live.local_server, backend.cli
assert "fastapi.testclient" not in sys.modules and "starlette.testclient" not in sys.modules
print("ok")
"""


def test_the_virtual_study_imports_without_httpx() -> None:
    r = subprocess.run([sys.executable, "-c", NO_HTTPX], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == "ok"


def test_the_plain_client_talks_to_a_real_server() -> None:
    app = FastAPI()

    @app.post("/echo")
    def echo(body: dict[str, int], authorization: str = Header(default="")) -> dict[str, object]:
        return {"sum": sum(body.values()), "auth": authorization}

    @app.get("/q")
    def q(x: int) -> dict[str, int]:
        return {"x2": 2 * x}

    with serving(app) as client:
        client.token = "t0k"
        r = client.post("/echo", json={"a": 2, "b": 3})
        assert r.status_code == 200 and r.json() == {"sum": 5, "auth": "Bearer t0k"}
        assert client.get("/q", params={"x": 21}).json() == {"x2": 42}
        bad = client.get("/q", params={"x": "nope"})
        assert bad.status_code == 422 and "x" in bad.text
        assert client.get("/missing").status_code == 404
